"""Several ranks under mpirun (Open MPI, `--oversubscribe`: 2 ranks on PoCL's one CPU device), against the
tiny trained scene of the `stages` fixture: `stylize`, `render`, `eval style` and `eval table` over 2 ranks
write exactly the files 1 process writes (every frame and depth map bitwise, the same per-view losses and
scores); each training stage over 2 ranks takes the steps 1 process taking both ranks' sub-batches takes,
and its checkpoint resumes on 1 rank; a rank that fails, is killed or hangs stops the whole job with a
message naming it, the last checkpoint intact; a command that does not split its work refuses several
ranks. Skipped, and reported so, where MPI is absent or the tool was built without it.
"""
import filecmp
import json
import os
import shutil
import signal
import struct
import subprocess
import time
from array import array

import pytest

from conftest import cli_path, run_cli


def mpi_missing() -> str:
    if not shutil.which("mpirun"):
        return "no mpirun on PATH (apt-get install openmpi-bin libopenmpi-dev, then rebuild)"
    code, out = run_cli("--version")
    if "MPI: yes" not in out:
        return "this stylerf was built without MPI"
    return ""


pytestmark = pytest.mark.skipif(bool(mpi_missing()), reason=mpi_missing() or "MPI is here")


def mpirun(ranks: int, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", POCL_MAX_PTHREAD_COUNT="1")
    return subprocess.run(["mpirun", "-np", str(ranks), "--oversubscribe", cli_path(), *args], env=env,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout)


def files_under(root: str):
    return sorted(os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs)


def test_two_ranks_write_what_one_process_writes(stages, tmp_path):
    args = ["stylize", "--ckpt", stages.style, "--style", stages.style_images[0], "--style", stages.style_images[1],
            "--views", "path", "--frames", "5", "--cache", "none"]
    one, two = str(tmp_path / "one"), str(tmp_path / "two")
    r1 = mpirun(1, *args, "-o", one)
    assert r1.returncode == 0, r1.stdout
    r2 = mpirun(2, *args, "-o", two)
    assert r2.returncode == 0, r2.stdout
    assert "rank 1:" in r2.stdout  # rank 0 lists every rank's device
    names = [n for n in files_under(one) if n.endswith((".png", ".exr"))]
    assert len(names) >= 2 * 5 + 5, names
    assert names == [n for n in files_under(two) if n.endswith((".png", ".exr"))]
    for n in names:
        assert filecmp.cmp(os.path.join(one, n), os.path.join(two, n), shallow=False), n
    m1, m2 = (json.load(open(os.path.join(d, "metrics.json"))) for d in (one, two))
    assert m1["per_view"] == m2["per_view"]
    assert m2["ranks"]["ranks"] == 2 and m2["ranks"]["frames"] == 10


@pytest.mark.parametrize("views", ["path", "test"])
def test_render_over_two_ranks_writes_what_one_process_writes(stages, tmp_path, views):
    args = ["render", "--ckpt", os.path.join(stages.root, "d.ckpt"), "--views", views, "--frames", "5"]
    one, two = str(tmp_path / "one"), str(tmp_path / "two")
    for ranks, out in ((1, one), (2, two)):
        r = mpirun(ranks, *args, "-o", out)
        assert r.returncode == 0, r.stdout
    names = files_under(one)
    assert names == files_under(two) and len(names) >= 5, names
    for n in names:
        if n.endswith((".png", ".exr")):
            assert filecmp.cmp(os.path.join(one, n), os.path.join(two, n), shallow=False), n
    if views == "test":
        m1, m2 = (json.load(open(os.path.join(d, "metrics.json"))) for d in (one, two))
        assert m1["views"] == m2["views"] and m1["mean_psnr"] == pytest.approx(m2["mean_psnr"], rel=1e-12)


def test_a_failing_rank_stops_the_job_and_says_which(stages, tmp_path):
    # Every rank fails here (a missing style image), rank 0 or not; the job must end, not hang, and say so.
    r = mpirun(2, "stylize", "--ckpt", stages.style, "--style", str(tmp_path / "missing.png"), "--views", "path",
               "--frames", "2", "-o", str(tmp_path / "out"), timeout=120)
    assert r.returncode != 0
    assert "missing.png" in r.stdout and "error" in r.stdout


def checkpoint_tensors(path: str) -> dict:
    """A checkpoint's float32 tensors by name (safetensors: a little-endian u64 header length, a JSON header)."""
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    out = {}
    for name, info in header.items():
        if name != "__metadata__" and info["dtype"] == "F32":
            begin, end = info["data_offsets"]
            out[name] = array("f", data[begin:end])
    return out


def largest_relative_difference(a: str, b: str) -> float:
    """Over every tensor of two checkpoints: max |a - b| over the tensor's largest |a| (1 where it is 0)."""
    ta, tb = checkpoint_tensors(a), checkpoint_tensors(b)
    assert sorted(ta) == sorted(tb)
    worst = 0.0
    for name, x in ta.items():
        y = tb[name]
        assert len(x) == len(y), name
        scale = max((abs(v) for v in x), default=0.0) or 1.0
        worst = max(worst, max((abs(u - v) for u, v in zip(x, y)), default=0.0) / scale)
    return worst


# 8 2D warm-start steps, then rendered steps: both kinds of step, the second with SICT's running statistics.
# Constant learning rates: a run of 10 steps resumed to 20 then has the rates of a run of 20.
STYLE_ARGS = ["--warm-start", "8", "--holdout-styles", "1", "--eval-every", "0", "--log-every", "5", "--lr-decay", "1"]
# An upsampling and an alpha-mask update within the 20 steps, so the ranks must take those events alike too.
DENSITY_ARGS = ["--iters", "20", "--batch", "1024", "--upsample-at", "8", "--mask-at", "12", "--init-voxels", "32768",
                "--final-voxels", "64000", "--log-every", "5"]


def stage_commands(stages):
    """Each stage's command for 20 steps, and its flag for the sub-batches a step of one process takes."""
    return {
        "density": (["train-density", "--scene", stages.scene, *DENSITY_ARGS], "--batch-slices"),
        "features": (["train-features", "--density", stages.density, "--iters", "20", "--log-every", "5"],
                     "--patches-per-step"),
        "style": (["train-style", "--features", stages.features, "--styles", stages.styles, *STYLE_ARGS, "--iters", "20"],
                  "--styles-per-step"),
    }


@pytest.fixture(scope="module")
def stage_runs(stages, tmp_path_factory):
    """Each stage for 20 steps on 2 ranks, on 1 rank taking both ranks' sub-batches, and on 1 rank taking one."""
    root = tmp_path_factory.mktemp("mpi-stages")
    paths = {}
    for stage, (cmd, flag) in stage_commands(stages).items():
        for name, ranks, extra in (("two", 2, []), ("one_by_two", 1, [flag, "2"]), ("one", 1, [])):
            paths[stage, name] = str(root / f"{stage}-{name}.ckpt")
            r = mpirun(ranks, *cmd, *extra, "-o", paths[stage, name])
            assert r.returncode == 0, r.stdout
            if name == "two":
                assert "round robin over 2 ranks" in r.stdout, r.stdout
                assert "gradients summed over 2 ranks" in r.stdout or "on 2 ranks" in r.stdout, r.stdout
    return paths


@pytest.mark.parametrize("stage", ["density", "features", "style"])
def test_two_ranks_train_as_one_process_taking_both_ranks_sub_batches(stage_runs, stage):
    # Every parameter, Adam moment and running statistic of the checkpoints (measured: bitwise equal).
    assert largest_relative_difference(stage_runs[stage, "two"], stage_runs[stage, "one_by_two"]) <= 1e-5
    if stage == "density":
        # The slices are one batch cut in two: the whole batch at once differs only in the order of the sums.
        assert largest_relative_difference(stage_runs[stage, "two"], stage_runs[stage, "one"]) <= 1e-4
    else:
        # The ranks did take different patches or styles: one a step is another run.
        assert largest_relative_difference(stage_runs[stage, "two"], stage_runs[stage, "one"]) > 1e-3


def test_a_two_rank_style_checkpoint_resumes_on_one_rank_where_it_left_off(stages, stage_runs, tmp_path):
    cmd, _ = stage_commands(stages)["style"]
    half = str(tmp_path / "half.ckpt")
    r = mpirun(2, *[a if a != "20" else "10" for a in cmd], "-o", half)
    assert r.returncode == 0, r.stdout
    r = mpirun(1, "train-style", "--resume", "--iters", "20", *STYLE_ARGS, "-o", half)
    assert r.returncode == 0, r.stdout
    assert "resuming from" in r.stdout and "2 styles a step" in r.stdout, r.stdout
    # Each style's draws depend on its index alone, and the optimiser's state is in the checkpoint.
    assert largest_relative_difference(stage_runs["style", "two"], half) <= 1e-5


@pytest.mark.parametrize("stage", ["density", "features"])
def test_a_two_rank_checkpoint_resumes_on_one_rank(stages, stage_runs, stage, tmp_path):
    ckpt = str(tmp_path / "resumed.ckpt")
    shutil.copy(stage_runs[stage, "two"], ckpt)
    command = ["train-density", "--scene", stages.scene] if stage == "density" else ["train-features"]
    r = mpirun(1, *command, "--resume", "--iters", "24", "--log-every", "2", "-o", ckpt)
    assert r.returncode == 0, r.stdout
    assert "resuming from" in r.stdout and "it 24/24" in r.stdout, r.stdout
    # The step still takes the two ranks' sub-batches: the checkpoint keeps them.
    assert "in 2 slices" in r.stdout if stage == "density" else "2 patches a step" in r.stdout, r.stdout


def test_eval_style_over_two_ranks_writes_what_one_process_writes(stages, tmp_path):
    args = ["eval", "style", "--ckpt", stages.style, "--styles", stages.styles, "--max-views", "2"]
    for ranks in (1, 2):
        r = mpirun(ranks, *args, "-o", str(tmp_path / f"sheets{ranks}"), "--json", str(tmp_path / f"eval{ranks}.json"))
        assert r.returncode == 0, r.stdout
        assert "mean over 3 styles" in r.stdout, r.stdout
    assert (tmp_path / "eval1.json").read_text() == (tmp_path / "eval2.json").read_text()
    names = files_under(str(tmp_path / "sheets1"))
    assert len(names) == 3 and names == files_under(str(tmp_path / "sheets2"))
    for n in names:
        assert filecmp.cmp(str(tmp_path / "sheets1" / n), str(tmp_path / "sheets2" / n), shallow=False), n


def test_eval_table_over_two_ranks_writes_what_one_process_writes(stages, tmp_path):
    args = ["eval", "table", "--scene-ckpts", f"{stages.density},{stages.style}", "--styles", stages.styles,
            "--max-styles", "3", "--scored-frames", "9", "--path-frames", "30", "--no-lpips"]
    tables = []
    for ranks in (1, 2):
        out = tmp_path / f"table{ranks}"
        r = mpirun(ranks, *args, "-o", str(out))
        assert r.returncode == 0, r.stdout
        table = json.loads((out / "table.json").read_text())
        table.pop("seconds")  # the only thing that may differ: the time it took
        tables.append(table)
        names = files_under(str(out))
        assert "table.md" in names and any(n.endswith("side_by_side.mp4") for n in names), names
    assert tables[0] == tables[1]
    assert len(tables[0]["scenes"][0]["methods"][1]["per_style"]) == 3
    md = [(tmp_path / f"table{k}" / "table.md").read_text().rsplit("\n(", 1)[0] for k in (1, 2)]
    assert md[0] == md[1]
    frames = sorted(n for n in files_under(str(tmp_path / "table1")) if n.endswith(".png"))
    assert frames and frames == sorted(n for n in files_under(str(tmp_path / "table2")) if n.endswith(".png"))
    for n in frames:
        assert filecmp.cmp(str(tmp_path / "table1" / n), str(tmp_path / "table2" / n), shallow=False), n


def test_run_starts_the_steps_that_split_under_mpirun(stages, tmp_path):
    code, out = run_cli("demo-images", "-o", str(tmp_path), "--size", "64", "--num-styles", "8")
    assert code == 0, out
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", POCL_MAX_PTHREAD_COUNT="1")
    args = [cli_path(), "run", "--scene", stages.scene, "--styles", str(tmp_path / "styles"), "-o",
            str(tmp_path / "run"), "--holdout-styles", "2", "--stage-iters", "150,20,6", "--frames", "3",
            "--eval-views", "1", "--table-frames", "8", "--max-videos", "1", "--ranks", "2"]
    r = subprocess.run(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    assert r.returncode == 0, r.stdout
    for step in ("density", "features", "style", "style_eval", "videos", "consistency"):
        assert f"== {step}: mpirun -np 2 stylerf " in r.stdout, (step, r.stdout)
    log = (tmp_path / "run" / "logs" / "style.log").read_text()
    assert "rank 1:" in log and "2 styles a step" in log, log
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["style_loss_ratio"] > 0
    assert (tmp_path / "run" / "videos" / "metrics.json").exists()
    # Resumed with the same ranks: every step kept.
    again = subprocess.run(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    assert again.returncode == 0, again.stdout
    assert ": stylerf" not in again.stdout and "-np 2 stylerf" not in again.stdout, again.stdout
    # A launcher that is not there is refused before any work.
    bad_args = [str(tmp_path / "bad") if a == str(tmp_path / "run") else a for a in args]
    bad = subprocess.run([*bad_args, "--mpirun", "no-such-mpirun --bind-to core"], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True, timeout=60)
    assert bad.returncode != 0
    assert "--mpirun 'no-such-mpirun --bind-to core': 'no-such-mpirun' is not on PATH" in bad.stdout, bad.stdout
    assert not (tmp_path / "bad").exists()


def rank_pids(marker: str, rank: int):
    """The pids of processes whose command line holds `marker` and whose Open MPI rank is `rank`."""
    pids = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if marker.encode() not in f.read():
                    continue
            with open(f"/proc/{pid}/environ", "rb") as f:
                if f"OMPI_COMM_WORLD_RANK={rank}".encode() in f.read().split(b"\0"):
                    pids.append(int(pid))
        except OSError:
            continue
    return pids


def test_a_killed_rank_stops_training_and_leaves_the_last_checkpoint(stages, tmp_path):
    out = str(tmp_path / "killed.ckpt")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", POCL_MAX_PTHREAD_COUNT="1")
    job = subprocess.Popen(["mpirun", "-np", "2", "--oversubscribe", cli_path(), "train-style", "--features",
                            stages.features, "--styles", stages.styles, *STYLE_ARGS, "--iters", "100000",
                            "--ckpt-every", "3", "-o", out], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.time() + 300
        while not os.path.exists(out) and time.time() < deadline and job.poll() is None:
            time.sleep(0.5)
        assert os.path.exists(out), "no checkpoint was written"
        victims = rank_pids(out, 1)
        assert len(victims) == 1, victims
        os.kill(victims[0], signal.SIGKILL)
        output, _ = job.communicate(timeout=120)  # the job ends, bounded: no rank waits forever
    finally:
        if job.poll() is None:
            job.kill()
    assert job.returncode != 0
    assert "rank 1" in output, output
    # The last checkpoint loads, and training goes on from it on one rank.
    r = mpirun(1, "train-style", "--resume", "--minutes", "0.02", *STYLE_ARGS, "-o", out)
    assert r.returncode == 0, r.stdout
    assert "resuming from" in r.stdout


@pytest.mark.parametrize("victim", [1, 0])
def test_a_stopped_rank_ends_the_job_in_bounded_time_naming_it(stages, tmp_path, victim):
    """A rank that hangs without dying (SIGSTOP) is named by one that waits for it, within the time limit."""
    out = str(tmp_path / "stopped.ckpt")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", POCL_MAX_PTHREAD_COUNT="1", STYLERF_RANK_TIMEOUT_S="5")
    job = subprocess.Popen(["mpirun", "-np", "2", "--oversubscribe", cli_path(), "train-style", "--features",
                            stages.features, "--styles", stages.styles, *STYLE_ARGS, "--iters", "100000",
                            "--ckpt-every", "3", "-o", out], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True)
    victims = []
    try:
        deadline = time.time() + 300
        while not os.path.exists(out) and time.time() < deadline and job.poll() is None:
            time.sleep(0.5)
        assert os.path.exists(out), "no checkpoint was written"
        victims = rank_pids(out, victim)
        assert len(victims) == 1, victims
        os.kill(victims[0], signal.SIGSTOP)
        stopped_at = time.time()
        output, _ = job.communicate(timeout=90)  # 5 s of silence, then the job ends
        ended_after = time.time() - stopped_at
    finally:
        for pid in victims:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        if job.poll() is None:
            job.kill()
    assert job.returncode != 0
    assert f"rank {victim} of 2 has not been heard from" in output, output
    assert ended_after < 60, ended_after
    r = mpirun(1, "train-style", "--resume", "--minutes", "0.02", *STYLE_ARGS, "-o", out)
    assert r.returncode == 0, r.stdout
    assert "resuming from" in r.stdout


def test_a_bad_rank_time_limit_is_refused_by_name(stages, tmp_path):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", STYLERF_RANK_TIMEOUT_S="soon")
    r = subprocess.run(["mpirun", "-np", "2", "--oversubscribe", cli_path(), "make-scene", "-o",
                        str(tmp_path / "scene")], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True, timeout=120)
    assert r.returncode != 0
    assert "STYLERF_RANK_TIMEOUT_S='soon' is not a positive number of seconds" in r.stdout, r.stdout


def test_a_command_that_does_not_split_its_work_refuses_two_ranks(stages, tmp_path):
    r = mpirun(2, "make-scene", "-o", str(tmp_path / "scene"), "--size", "16", "--num-views", "4")
    assert r.returncode != 0
    assert "runs on one rank only" in r.stdout, r.stdout
    assert not os.path.exists(tmp_path / "scene")
    r = mpirun(2, "run", "--scene", stages.scene, "--styles", stages.styles, "-o", str(tmp_path / "run"))
    assert r.returncode != 0
    assert "`stylerf run --ranks N` starts those under mpirun itself" in r.stdout, r.stdout
    assert not os.path.exists(tmp_path / "run")
