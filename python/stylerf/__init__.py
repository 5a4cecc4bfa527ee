"""stylerf: zero-shot 3D style transfer of radiance fields (StyleRF, CVPR 2023) on any OpenCL device.

Images are numpy arrays, H x W x 3, float32 in [0, 1] (uint8 is accepted on input). The library works on
its own threads with the GIL released; its errors arrive as stylerf.Error with the library's message, bad
arguments as ValueError naming the argument.
"""
import atexit as _atexit

from ._stylerf import (  # noqa: F401  (the public API)
    Camera,
    Error,
    Scene,
    StyleCode,
    StyleModel,
    __version__,
    consistency,
    device,
    devices,
    load_image,
    lpips,
    mix,
    save_image,
    train_density,
    train_features,
    train_style,
    use_device,
)
from ._stylerf import _shutdown

# PoCL compiles kernels on worker threads: the queue must be drained before the interpreter tears down.
_atexit.register(_shutdown)

__all__ = [
    "Camera", "Error", "Scene", "StyleCode", "StyleModel", "__version__", "consistency", "device", "devices",
    "load_image", "lpips", "mix", "save_image", "train_density", "train_features", "train_style", "use_device",
]
