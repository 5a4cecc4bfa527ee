"""The pytest suite of the Python module: a generated scene (the built `stylerf make-scene`, 32 px), procedural
style images (`stylerf demo-images`), and the three stages trained on them from Python, briefly (the
plumbing is under test, not the quality). No ../shared; the weights come from scripts/fetch_weights.sh.

Run by CTest (python_pytest), which sets PYTHONPATH to <build>/python and STYLERF_CLI to the built tool.
"""
import os
import subprocess

import pytest

import stylerf


def cli_path():
    path = os.environ.get("STYLERF_CLI", "")
    if not path or not os.access(path, os.X_OK):
        raise RuntimeError("STYLERF_CLI must name the built stylerf tool (CTest sets it)")
    return path


def run_cli(*args):
    """The built tool's exit code and its output (stdout and stderr together)."""
    r = subprocess.run([cli_path(), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return r.returncode, r.stdout


class Stages:
    """Checkpoint paths of the three stages, the scene folder and the style images."""

    def __init__(self, root):
        self.root = str(root)
        self.scene = os.path.join(self.root, "scene")
        self.styles = os.path.join(self.root, "demo", "styles")
        code, out = run_cli("make-scene", "-o", self.scene, "--size", "32", "--num-views", "20")
        assert code == 0, out
        code, out = run_cli("demo-images", "-o", os.path.join(self.root, "demo"), "--size", "64", "--num-styles", "3")
        assert code == 0, out
        self.style_images = sorted(os.path.join(self.styles, f) for f in os.listdir(self.styles))
        self.density = stylerf.train_density(stylerf.Scene.open(self.scene), os.path.join(self.root, "d.ckpt"),
                                             iters=150, batch=1024)
        self.features = stylerf.train_features(self.density, os.path.join(self.root, "f.ckpt"), iters=20)
        self.style = stylerf.train_style(self.features, self.styles, os.path.join(self.root, "s.ckpt"), iters=4,
                                         holdout_styles=1)


@pytest.fixture(scope="session")
def stages(tmp_path_factory):
    return Stages(tmp_path_factory.mktemp("stylerf"))


@pytest.fixture(scope="session")
def model(stages):
    return stylerf.StyleModel.open(stages.style)
