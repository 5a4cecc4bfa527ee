"""The trainers' progress callback, stopping, exceptions raised in it, and the GIL released meanwhile."""
import os
import threading
import time

import pytest

import stylerf


class Stop(Exception):
    pass


def test_progress_is_called_every_step(stages, tmp_path):
    seen = []
    out = stylerf.train_features(stages.density, str(tmp_path / "f.ckpt"), iters=6, progress=seen.append)
    assert os.path.getsize(out) > 0
    assert [d["iteration"] for d in seen] == [1, 2, 3, 4, 5, 6]
    assert all(d["stage"] == "features" and d["total"] == 6 for d in seen)


def test_a_time_budget_ends_the_run(stages, tmp_path):
    seen = []
    out = stylerf.train_density(stylerf.Scene.open(stages.scene), str(tmp_path / "d.ckpt"), minutes=0.01,
                                batch=256, progress=seen.append)
    assert os.path.getsize(out) > 0 and len(seen) > 0
    # The budget, not TensoRF's 30000 steps, set the schedule and ended the run (at or just before the total
    # the schedule was last fitted to). No bound on the wall time: that would measure the machine.
    assert seen[-1]["iteration"] <= seen[-1]["total"] < 30000
    assert [d["iteration"] for d in seen] == list(range(1, len(seen) + 1))


def test_false_stops_early_and_writes_the_checkpoint(stages, tmp_path):
    seen = []
    out = str(tmp_path / "d.ckpt")
    stylerf.train_density(stylerf.Scene.open(stages.scene), out, iters=50, batch=256,
                          progress=lambda d: seen.append(d["iteration"]) or d["iteration"] < 3)
    assert seen == [1, 2, 3] and os.path.getsize(out) > 0


@pytest.mark.parametrize("stage", ["density", "features", "style"])
def test_an_exception_in_the_callback_stops_cleanly(stages, tmp_path, stage):
    def progress(d):
        if d["iteration"] == 2:
            raise Stop("from the callback")

    out = str(tmp_path / "x.ckpt")
    with pytest.raises(Stop, match="from the callback"):
        if stage == "density":
            stylerf.train_density(stylerf.Scene.open(stages.scene), out, iters=20, batch=256, progress=progress)
        elif stage == "features":
            stylerf.train_features(stages.density, out, iters=20, progress=progress)
        else:
            stylerf.train_style(stages.features, stages.styles, out, iters=20, holdout=1, progress=progress)
    assert os.listdir(tmp_path) == [], "no checkpoint and no temporary file may be left"


def test_an_existing_checkpoint_is_kept_unless_overwrite(stages, tmp_path):
    out = tmp_path / "f.ckpt"
    out.write_bytes(b"keep")
    with pytest.raises(FileExistsError):
        stylerf.train_features(stages.density, str(out), iters=1)
    assert out.read_bytes() == b"keep"


def test_the_gil_is_released_while_training(stages, tmp_path):
    # Without the release the main thread could not run at all until the call returned. A time budget (0.6 s
    # of steps) rather than a step count keeps the call long enough on any machine, however fast.
    scene = stylerf.Scene.open(stages.scene)
    worker = threading.Thread(target=stylerf.train_density,
                              args=(scene, str(tmp_path / "d.ckpt")), kwargs={"minutes": 0.01, "batch": 256})
    ticks = 0
    worker.start()
    while worker.is_alive():
        ticks += 1
        time.sleep(0.002)
    worker.join()
    assert ticks > 20


def test_checkpoints_equal_the_clis_byte_for_byte(stages, tmp_path):
    from conftest import run_cli

    def same(cli_args, train):
        cli, ours = str(tmp_path / "cli.ckpt"), str(tmp_path / "py.ckpt")
        code, log = run_cli(*cli_args, "-o", cli)
        assert code == 0, log
        train(ours)
        with open(cli, "rb") as a, open(ours, "rb") as b:
            assert a.read() == b.read()
        os.remove(cli)
        os.remove(ours)

    same(["train-density", "--scene", stages.scene, "--iters", "12", "--batch", "256", "--eval-views", "1"],
         lambda out: stylerf.train_density(stylerf.Scene.open(stages.scene), out, iters=12, batch=256))
    same(["train-features", "--density", stages.density, "--iters", "3", "--eval-views", "1"],
         lambda out: stylerf.train_features(stages.density, out, iters=3))
    same(["train-style", "--features", stages.features, "--styles", stages.styles, "--holdout-styles", "1",
          "--iters", "3"],
         lambda out: stylerf.train_style(stages.features, stages.styles, out, iters=3, holdout=1))
