"""The trainers' progress callback, stopping, exceptions raised in it, and the GIL released meanwhile."""
import os
import sys
import threading

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
    # The budget, not TensoRF's 30000 steps, ended the run, at or before the total its schedule was last
    # fitted to. How many steps fit in 0.6 s measures the machine, so nothing here depends on it: only
    # where the run was long enough for a refit (the first after 10 measured steps, lib/train/budget.hpp)
    # must the budget have fitted the schedule too. The refit's arithmetic is tested on a scripted clock
    # (tests/test_train_budget.cpp).
    assert seen[-1]["iteration"] <= seen[-1]["total"]
    assert seen[-1]["iteration"] < 30000
    if len(seen) > 20:
        assert seen[-1]["total"] < 30000
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
            stylerf.train_style(stages.features, stages.styles, out, iters=20, holdout_styles=1, progress=progress)
    assert os.listdir(tmp_path) == [], "no checkpoint and no temporary file may be left"


def test_the_gil_is_released_while_training(stages, tmp_path):
    # No clock: with a switch interval far longer than the run, a thread that holds the GIL keeps it until it
    # blocks or ends, so the main thread, woken by the first step's callback, can only run before the run
    # ends if the steps themselves release the GIL. Holding it through the call would let the main thread
    # in only after the last of the 200 steps.
    scene = stylerf.Scene.open(stages.scene)
    iters = 200
    seen, started = [], threading.Event()

    def progress(d):
        seen.append(d["iteration"])
        if d["iteration"] == 1:
            started.set()

    def train():
        try:
            stylerf.train_density(scene, str(tmp_path / "d.ckpt"), iters=iters, batch=256, progress=progress)
        finally:
            started.set()  # a run that fails before its first step must not leave the main thread waiting

    worker = threading.Thread(target=train)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1000.0)
    try:
        worker.start()
        started.wait()
        steps_when_main_ran = len(seen)
        worker.join()
    finally:
        sys.setswitchinterval(interval)
    assert seen == list(range(1, iters + 1))
    assert steps_when_main_ran < iters


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
         lambda out: stylerf.train_style(stages.features, stages.styles, out, iters=3, holdout_styles=1))
