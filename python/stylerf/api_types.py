"""The types of stylerf's arguments and results, for type checkers and for reading.

The results are plain dicts at run time; these TypedDicts say which keys each holds and what type each value
has. The aliases name the kinds of argument the functions take.
"""
import os
from typing import TYPE_CHECKING, Callable, Literal, Optional, TypedDict, Union

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from . import Camera  # as the stubs declare it: the extension module has no stubs of its own
else:
    from ._stylerf import Camera

# A file or folder: a str or any os.PathLike, such as pathlib.Path.
PathLike = Union[str, "os.PathLike[str]"]
# An image as the library returns it: H x W x 3 float32 in [0, 1].
FloatImage = npt.NDArray[np.float32]
# An image as the library accepts it: H x W x 3, float32 in [0, 1] or uint8.
ImageLike = Union[npt.NDArray[np.float32], npt.NDArray[np.uint8]]
# A view of a StyleModel: an index into its cameras, or a Camera.
View = Union[int, Camera]
# Rays per feature block: n (n x n, 1 to 8) or the quincunx pattern.
Supersample = Union[int, Literal["quincunx"]]
# The network LPIPS compares features of.
LpipsNet = Literal["alex", "vgg"]
# The feature stage's profile: features at 1/4 resolution with an upsampling decoder, or the paper's.
Profile = Literal["fast", "paper"]
# A style stage's named settings: the best measured, or the paper's.
Recipe = Literal["fast", "paper"]


class DeviceInfo(TypedDict):
    """An OpenCL device, as devices() lists it."""

    index: int
    name: str
    vendor: str
    type: Literal["gpu", "cpu", "accelerator", "other"]
    platform: str
    global_mem_bytes: int
    compute_units: int


class ActiveDevice(DeviceInfo):
    """The device in use, as device() describes it; denormals_flushed: whether its kernels flush floats below
    1e-38 to zero."""

    denormals_flushed: bool


class RenderResult(TypedDict):
    """StyleModel.render's result: rgb at the camera's size, depth and opacity at 1/stride of it."""

    rgb: npt.NDArray[np.float32]
    depth: npt.NDArray[np.float32]
    opacity: npt.NDArray[np.float32]
    stride: int


class RangeScore(TypedDict):
    """One range of consistency(): frames t and t - k compared over k-apart pairs; lpips is None when it was
    not measured."""

    k: int
    rmse: float
    lpips: Optional[float]
    valid_fraction: float
    pairs: int
    skipped: int


class ConsistencyScore(TypedDict):
    """consistency()'s result: the short range (k = 1) and the long range (k = 7)."""

    short_range: RangeScore
    long_range: RangeScore


class DensityProgress(TypedDict):
    """What train_density's progress callback gets after every step."""

    stage: Literal["density"]
    iteration: int
    total: int
    mse: float
    psnr: float
    seconds: float


class FeatureProgress(TypedDict):
    """What train_features' progress callback gets after every step: a ray step measures feature_mse, a
    patch step (patch True) pixel_mse; the other is None."""

    stage: Literal["features"]
    iteration: int
    total: int
    patch: bool
    feature_mse: Optional[float]
    pixel_mse: Optional[float]
    seconds: float


class StyleProgress(TypedDict):
    """What train_style's progress callback gets after every step (warm: whether it was a warm-start step)."""

    stage: Literal["style"]
    iteration: int
    total: int
    warm: bool
    content: float
    style: float
    seconds: float


# A trainer's progress callback: returning False stops training early (the checkpoint is written as at the
# end of a run); None or True goes on.
DensityCallback = Callable[[DensityProgress], Optional[bool]]
FeatureCallback = Callable[[FeatureProgress], Optional[bool]]
StyleCallback = Callable[[StyleProgress], Optional[bool]]
