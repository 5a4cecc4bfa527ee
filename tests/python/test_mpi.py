"""Several ranks under mpirun (Open MPI, `--oversubscribe`: 2 ranks on PoCL's one CPU device), against the
tiny trained scene of the `stages` fixture: `stylize` over 2 ranks writes exactly the files 1 process
writes (every frame and depth map bitwise, the same per-view losses), and a rank that fails stops the
whole job with a message naming it. Skipped, and reported so, where MPI is absent or the tool was built
without it.
"""
import filecmp
import json
import os
import shutil
import subprocess

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
