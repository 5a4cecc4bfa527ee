"""stylerf: zero-shot 3D style transfer of radiance fields (StyleRF, CVPR 2023) on any OpenCL device.

Images are numpy arrays, H x W x 3, float32 in [0, 1] (uint8 is accepted on input). Paths are str or any
os.PathLike (pathlib.Path); None stands for "none" or "the default". The library works on its own threads
with the GIL released; its errors arrive as stylerf.Error with the library's message, bad arguments as
ValueError naming the argument. help(stylerf.StyleModel.stylize) and the others document each call; the
types of arguments and results are in stylerf.api_types.
"""
import atexit as _atexit

from ._stylerf import (  # noqa: F401  (the public API)
    Camera,
    Error,
    Scene,
    StyleCode,
    StyleModel,
    __commit__,
    __version__,
    consistency,
    device,
    devices,
    load_image,
    lpips,
    mix,
    save_image,
    save_video,
    train_density,
    train_features,
    train_style,
    use_device,
)
from ._stylerf import _shutdown
from .api_types import (  # noqa: F401  (the types the stubs name)
    ActiveDevice,
    ConsistencyScore,
    DensityCallback,
    DensityProgress,
    DeviceInfo,
    FeatureCallback,
    FeatureProgress,
    FloatImage,
    ImageLike,
    LpipsNet,
    PathLike,
    Profile,
    RangeScore,
    Recipe,
    RenderResult,
    StyleCallback,
    StyleProgress,
    Supersample,
    View,
)

# PoCL compiles kernels on worker threads: the queue must be drained before the interpreter tears down.
_atexit.register(_shutdown)

__all__ = [
    "Camera", "Error", "Scene", "StyleCode", "StyleModel", "__commit__", "__version__", "consistency", "device",
    "devices", "load_image", "lpips", "mix", "save_image", "save_video", "train_density", "train_features",
    "train_style", "use_device",
    "ActiveDevice", "ConsistencyScore", "DensityCallback", "DensityProgress", "DeviceInfo", "FeatureCallback",
    "FeatureProgress", "FloatImage", "ImageLike", "LpipsNet", "PathLike", "Profile", "RangeScore", "Recipe",
    "RenderResult", "StyleCallback", "StyleProgress", "Supersample", "View",
]
