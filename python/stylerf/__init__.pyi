# Type stubs of stylerf (the extension module stylerf._stylerf). Each docstring here is the one help() shows
# at run time (tests/python/test_api.py holds them equal).
from typing import List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from .api_types import ActiveDevice as ActiveDevice
from .api_types import ConsistencyScore as ConsistencyScore
from .api_types import DensityCallback as DensityCallback
from .api_types import DensityProgress as DensityProgress
from .api_types import DeviceInfo as DeviceInfo
from .api_types import FeatureCallback as FeatureCallback
from .api_types import FeatureProgress as FeatureProgress
from .api_types import FloatImage as FloatImage
from .api_types import ImageLike as ImageLike
from .api_types import LpipsNet as LpipsNet
from .api_types import PathLike as PathLike
from .api_types import Profile as Profile
from .api_types import RangeScore as RangeScore
from .api_types import Recipe as Recipe
from .api_types import RenderResult as RenderResult
from .api_types import StyleCallback as StyleCallback
from .api_types import StyleProgress as StyleProgress
from .api_types import Supersample as Supersample
from .api_types import View as View

__version__: str
__commit__: str

class Error(RuntimeError):
    """An error of the library (a missing file, a bad checkpoint, a device failure), its message unchanged."""

class Camera:
    """A pinhole camera: c2w camera-to-world (3 x 4 or 4 x 4, OpenGL axes: it looks down -z), intrinsics in
    pixels."""
    def __init__(self, c2w: npt.ArrayLike, fx: float, fy: float, cx: float, cy: float, w: int, h: int) -> None:
        """A camera from its pose (a rigid 3 x 4 or 4 x 4 matrix, float32 or float64), focal lengths, principal
        point and image size in pixels."""
    @property
    def c2w(self) -> npt.NDArray[np.float32]:
        """The 4 x 4 camera-to-world matrix (a copy)."""
    @property
    def fx(self) -> float:
        """Horizontal focal length in pixels."""
    @property
    def fy(self) -> float:
        """Vertical focal length in pixels."""
    @property
    def cx(self) -> float:
        """Principal point, x in pixels."""
    @property
    def cy(self) -> float:
        """Principal point, y in pixels."""
    @property
    def width(self) -> int:
        """Image width in pixels."""
    @property
    def height(self) -> int:
        """Image height in pixels."""
    def resized(self, w: int, h: int) -> Camera:
        """The same camera for a w x h image (intrinsics scaled with it)."""
    def with_longer_side(self, size: int) -> Camera:
        """The same camera with its longer side size pixels and its aspect kept (size <= 0: unchanged)."""

class Scene:
    """A scene folder (Blender, LLFF, COLMAP or nerfstudio)."""
    @staticmethod
    def open(path: PathLike, downsample: Optional[int] = None) -> Scene:
        """Loads the scene folder. downsample: the image downsample factor (None: the paper's resolution,
        Blender 1, LLFF 4, COLMAP and nerfstudio 1)."""
    @property
    def name(self) -> str:
        """The scene's name."""
    @property
    def format(self) -> str:
        """The folder's format as the loader found it: blender, or llff, colmap or nerfstudio with -forward or
        -object."""
    @property
    def path(self) -> str:
        """The folder, as given to open."""
    @property
    def downsample(self) -> int:
        """The downsample factor its images were loaded at."""
    @property
    def train_cameras(self) -> List[Camera]:
        """The training views' cameras."""
    @property
    def test_cameras(self) -> List[Camera]:
        """The held-out views' cameras (empty when the scene holds none out)."""
    def path_cameras(self, frames: int = 120) -> List[Camera]:
        """The scene's default camera path: an orbit, or a spiral for forward-facing scenes."""

class StyleCode:
    """A style image's code under one StyleModel (zero-shot: no optimisation)."""
    @property
    def source(self) -> str:
        """Where the code came from: the image's path, '<array>' for an array, or 'mix'."""

class StyleModel:
    """A trained style checkpoint on the scene it was trained on. A view is an index into cameras or a Camera."""
    @staticmethod
    def open(path: PathLike, scene: Optional[Union[Scene, PathLike]] = None) -> StyleModel:
        """Opens a train_style checkpoint. scene: the scene (a Scene or its folder) when it moved since training;
        None: the folder the checkpoint records."""
    @property
    def path(self) -> str:
        """The checkpoint's path."""
    @property
    def supersample(self) -> Supersample:
        """Rays per feature block that stylize uses by default: n (n x n) or 'quincunx'."""
    @property
    def strength(self) -> float:
        """Stylisation strength in [0, 1]: each ray's stylised features blended with its own (the checkpoint's
        by default, 1 unless set). Encode styles after setting it: a code carries the scene's statistics at the
        strength it was encoded at."""
    @strength.setter
    def strength(self, value: float) -> None:
        """Stylisation strength in [0, 1]: each ray's stylised features blended with its own (the checkpoint's
        by default, 1 unless set)."""
    @property
    def stride(self) -> int:
        """Pixels per feature-map cell along each side: the depth and opacity of render are at 1/stride of the
        image's resolution."""
    @property
    def cameras(self) -> List[Camera]:
        """The cameras a view index picks: the held-out views (the training views when there are none)."""
    def path_cameras(self, frames: int = 120) -> List[Camera]:
        """The scene's default camera path: an orbit, or a spiral for forward-facing scenes."""
    def encode_style(self, image: Union[PathLike, ImageLike]) -> StyleCode:
        """The code of a style image: a file path (read as `stylerf stylize --style` reads it) or an H x W x 3
        array (float32 in [0, 1] or uint8)."""
    def stylize(self, view: View, code: StyleCode, supersample: Optional[Supersample] = None) -> FloatImage:
        """The view stylised with code: H x W x 3 float32 in [0, 1]. supersample: rays per feature block, n
        (n x n, 1 to 8) or 'quincunx'; None: the model's."""
    def render(self, view: View) -> RenderResult:
        """The view without style: rgb (H x W x 3, the feature decoder's picture), and depth and opacity at
        1/stride of that resolution (the rays the model renders)."""

def devices() -> List[DeviceInfo]:
    """The OpenCL devices, in the order an index picks them."""

def use_device(spec: str) -> None:
    """Chooses the device before the first computation: spec is an index, cpu, gpu, accelerator, or part of a
    name (default: $STYLERF_DEVICE, else the first GPU, else the first device); once chosen it stays."""

def device() -> ActiveDevice:
    """The device in use (choosing the default one if none was chosen yet); denormals_flushed: whether its
    kernels flush floats below 1e-38 to zero (the library sets that up on CPU devices: x86 runs them slowly)."""

def mix(codes: Sequence[StyleCode], weights: Sequence[float]) -> StyleCode:
    """The code sum_k weights[k] * codes[k] (weights >= 0 summing to 1, codes of one model): it interpolates
    the style transformation itself."""

def load_image(path: PathLike) -> FloatImage:
    """An image file (PNG, JPEG, ...) as H x W x 3 float32 in [0, 1] (alpha dropped, grey replicated)."""

def save_image(path: PathLike, image: ImageLike) -> None:
    """Writes an H x W x 3 image (float32 in [0, 1] or uint8) to a PNG or JPEG file, by its name's extension,
    8 bits per channel, rounded."""

def save_video(frames: Sequence[ImageLike], path: PathLike, fps: float = 30.0) -> None:
    """Writes frames (a sequence of H x W x 3 images of one size, float32 in [0, 1] or uint8) to an mp4 video
    at fps frames a second, as the CLI writes its videos: H.264 through ffmpeg, which must be on PATH."""

def lpips(a: ImageLike, b: ImageLike, net: LpipsNet = "alex") -> float:
    """LPIPS (v0.1) between two H x W x 3 images of one size; net: alex or vgg."""

def consistency(model: StyleModel, code: StyleCode, *, frames: int = 16, path_frames: int = 120,
                size: Optional[int] = None, lpips: Optional[LpipsNet] = "alex",
                supersample: Optional[Supersample] = None) -> ConsistencyScore:
    """Short- and long-range consistency of the stylised camera path, as the paper's Table 1 (`stylerf eval
    consistency`): the first frames of a path_frames path, at size pixels on the longer side (None: the
    scene's), warped by the scene's geometry; RMSE, and LPIPS with that net (None: not measured)."""

def train_density(scene: Union[Scene, PathLike], out: PathLike, *, iters: Optional[int] = None,
                  minutes: Optional[float] = None, progress: Optional[DensityCallback] = None, seed: int = 0,
                  batch: int = 4096, checkpoint_every: int = 1000, force: bool = False) -> str:
    """Stage 1 (`stylerf train-density`): TensoRF's VM grids on the scene's images (a Scene or its folder).
    Give exactly one of iters and minutes. progress gets a dict after every step (returning False stops
    early). Writes the checkpoint out (force: replace an existing one) and returns its path."""

def train_features(density: PathLike, out: PathLike, *, scene: Optional[Union[Scene, PathLike]] = None,
                   iters: Optional[int] = None, minutes: Optional[float] = None,
                   progress: Optional[FeatureCallback] = None, profile: Profile = "fast", seed: int = 0,
                   checkpoint_every: int = 500, force: bool = False) -> str:
    """Stage 2 (`stylerf train-features`): the feature field and its decoder over a density checkpoint's
    frozen geometry. scene: a Scene or folder when the scene moved (None: the checkpoint's). profile: fast
    (features at 1/4 resolution) or paper. Lengths, progress, out and force as train_density's."""

def train_style(features: PathLike, styles: PathLike, out: PathLike, *,
                scene: Optional[Union[Scene, PathLike]] = None, iters: Optional[int] = None,
                minutes: Optional[float] = None, progress: Optional[StyleCallback] = None,
                holdout_styles: int = 12, recipe: Optional[Recipe] = None, seed: int = 0,
                checkpoint_every: int = 200, force: bool = False) -> str:
    """Stage 3 (`stylerf train-style`): SICT and DST over a feature checkpoint, trained on a folder of style
    images, holdout_styles of them held out. recipe: fast or paper (None: the one named like the feature
    checkpoint's profile). scene, lengths, progress, out and force as train_features'."""
