"""Arguments as a Python user gives them: paths as pathlib.Path or str, None for "none", the trainers taking
their scene alike (a Scene or its folder), and the CLI's option names."""
import os
import pathlib

import numpy as np
import pytest

import stylerf


def test_paths_may_be_pathlib_paths(stages, tmp_path):
    model = stylerf.StyleModel.open(pathlib.Path(stages.style))
    assert model.path == stages.style and isinstance(model.path, str)
    scene = stylerf.Scene.open(pathlib.Path(stages.scene))
    assert scene.path == stages.scene
    style = pathlib.Path(stages.style_images[0])
    assert np.array_equal(model.stylize(0, model.encode_style(style)),
                          model.stylize(0, model.encode_style(str(style))))
    image = stylerf.load_image(style)
    stylerf.save_image(tmp_path / "copy.png", image)
    assert np.array_equal(stylerf.load_image(tmp_path / "copy.png"), image)


def test_a_moved_scene_is_given_as_a_scene_or_a_folder(stages, model):
    by_folder = stylerf.StyleModel.open(stages.style, scene=pathlib.Path(stages.scene))
    by_scene = stylerf.StyleModel.open(stages.style, scene=stylerf.Scene.open(stages.scene))
    assert np.array_equal(by_folder.cameras[0].c2w, model.cameras[0].c2w)
    assert np.array_equal(by_scene.cameras[0].c2w, model.cameras[0].c2w)


def test_empty_paths_are_refused_naming_the_argument(stages):
    with pytest.raises(ValueError, match="^path: an empty path"):
        stylerf.StyleModel.open("")
    with pytest.raises(ValueError, match="^scene: an empty path"):
        stylerf.StyleModel.open(stages.style, scene="")
    with pytest.raises(ValueError, match="^path: an empty path"):
        stylerf.Scene.open("")
    with pytest.raises(ValueError, match="^out: an empty path"):
        stylerf.train_features(stages.density, "", iters=1)
    with pytest.raises(TypeError):
        stylerf.load_image(42)


def test_none_is_the_default(stages):
    default = stylerf.Scene.open(stages.scene, downsample=None)
    assert default.downsample == stylerf.Scene.open(stages.scene).downsample == 1
    assert stylerf.Scene.open(stages.scene, downsample=2).train_cameras[0].width == 16
    with pytest.raises(ValueError, match="^downsample: .*None for the scene's default"):
        stylerf.Scene.open(stages.scene, downsample=0)


def test_choices_are_checked_naming_the_argument(stages, tmp_path):
    with pytest.raises(ValueError, match="^profile: 'slow' is not one of: fast, paper"):
        stylerf.train_features(stages.density, tmp_path / "f.ckpt", iters=1, profile="slow")
    with pytest.raises(ValueError, match="^recipe: 'slow' is not one of: fast, paper"):
        stylerf.train_style(stages.features, stages.styles, tmp_path / "s.ckpt", iters=1, recipe="slow")
    with pytest.raises(ValueError, match="^holdout_styles: "):
        stylerf.train_style(stages.features, stages.styles, tmp_path / "s.ckpt", iters=1, holdout_styles=-1)
    assert os.listdir(tmp_path) == []


def test_the_trainers_take_paths_and_scenes_alike(stages, tmp_path):
    root = pathlib.Path(tmp_path)
    density = stylerf.train_density(pathlib.Path(stages.scene), root / "d.ckpt", iters=2, batch=256)
    assert density == str(root / "d.ckpt") and os.path.getsize(density) > 0
    scene = stylerf.Scene.open(stages.scene)
    features = stylerf.train_features(root / "d.ckpt", root / "f.ckpt", scene=scene, iters=2)
    assert os.path.getsize(features) > 0
    style = stylerf.train_style(pathlib.Path(stages.features), pathlib.Path(stages.styles), root / "s.ckpt",
                                scene=pathlib.Path(stages.scene), iters=1, holdout_styles=1)
    assert os.path.getsize(style) > 0
    assert stylerf.StyleModel.open(root / "s.ckpt").cameras[0].width == 32


def test_force_replaces_a_checkpoint(stages, tmp_path):
    out = tmp_path / "f.ckpt"
    out.write_bytes(b"old")
    with pytest.raises(FileExistsError, match="pass force=True"):
        stylerf.train_features(stages.density, out, iters=1)
    assert out.read_bytes() == b"old"
    stylerf.train_features(stages.density, out, iters=1, force=True)
    assert out.read_bytes() != b"old" and out.stat().st_size > 0


def test_a_feature_step_reports_only_what_it_measured(stages, tmp_path):
    seen = []
    stylerf.train_features(stages.density, tmp_path / "f.ckpt", iters=4, progress=seen.append)
    assert {d["patch"] for d in seen} == {True, False}, "ray and patch steps alternate"
    for d in seen:
        measured, other = ("pixel_mse", "feature_mse") if d["patch"] else ("feature_mse", "pixel_mse")
        assert d[other] is None and d[measured] >= 0


def test_lpips_not_measured_is_none(stages, model):
    code = model.encode_style(stages.style_images[0])
    score = stylerf.consistency(model, code, frames=8, path_frames=60, lpips=None)
    assert score["short_range"]["lpips"] is None and score["long_range"]["lpips"] is None
    with pytest.raises(ValueError, match="^size: .*None for the scene's"):
        stylerf.consistency(model, code, size=0)
