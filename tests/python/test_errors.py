"""Bad input: a ValueError naming the argument; the library's errors as stylerf.Error with its message."""
import numpy as np
import pytest

import stylerf
from conftest import run_cli


@pytest.fixture(scope="module")
def code(stages, model):
    return model.encode_style(stages.style_images[0])


GOOD = np.full((16, 16, 3), 0.5, dtype=np.float32)


@pytest.mark.parametrize("bad, words", [
    (GOOD.astype(np.float64), "dtype float64"),
    (GOOD[:, :, :2].copy(), "H x W x 3"),
    (np.zeros((16, 16), np.float32), "H x W x 3"),
    (np.full((16, 32, 3), 0.5, np.float32)[:, ::2], "not C-contiguous"),
    (np.where(np.arange(3) == 1, np.nan, GOOD).astype(np.float32), "NaN"),
    (GOOD + 1, "[0, 1]"),
    ([[0.5, 0.5, 0.5]], "numpy array"),
])
def test_bad_arrays_name_the_argument(model, bad, words):
    with pytest.raises(ValueError, match="^image: .*" + __import__("re").escape(words)):
        model.encode_style(bad)
    with pytest.raises(ValueError, match="^a: "):
        stylerf.lpips(bad, GOOD)


def test_bad_views_and_options(model, code):
    with pytest.raises(IndexError, match="view 99 is out of range"):
        model.stylize(99, code)
    with pytest.raises(ValueError, match="^supersample: "):
        model.stylize(0, code, supersample=0)
    with pytest.raises(ValueError, match="^supersample: supersample 'grid'"):
        model.stylize(0, code, supersample="grid")
    with pytest.raises(ValueError, match="^weights: .*sum to 1"):
        stylerf.mix([code, code], [0.7, 0.7])
    with pytest.raises(ValueError, match="^c2w: .*rigid"):
        stylerf.Camera(np.diag([2.0, 1, 1, 1]), 30, 30, 16, 16, 32, 32)
    with pytest.raises(ValueError, match="^fx: "):
        stylerf.Camera(np.eye(4), -1, 30, 16, 16, 32, 32)
    with pytest.raises(ValueError, match="^net: "):
        stylerf.lpips(GOOD, GOOD, net="resnet")
    with pytest.raises(ValueError, match="exactly one of iters= and minutes="):
        stylerf.train_features("x.ckpt", "y.ckpt")


def test_library_errors_carry_the_cli_message(stages, tmp_path):
    missing = str(tmp_path / "missing.ckpt")
    code, out = run_cli("stylize", "--ckpt", missing, "--style", stages.style_images[0], "-o", str(tmp_path / "o"))
    assert code == 1
    with pytest.raises(stylerf.Error) as e:
        stylerf.StyleModel.open(missing)
    assert isinstance(e.value, RuntimeError)
    assert "error: " + str(e.value) in out
    with pytest.raises(stylerf.Error, match="holds a 'features' stage, not a trained stylizer"):
        stylerf.StyleModel.open(stages.features)
