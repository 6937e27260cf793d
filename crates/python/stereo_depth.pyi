"""Type hints of the stereo_depth extension module (see docs/python.md)."""

import os
from typing import Any, Dict, Literal, Optional, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, "os.PathLike[str]"]
#: (H, W) grey or (H, W, 3|4) RGB(A), uint8 or uint16; or an image file.
ImageInput = Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16], PathLike]
FloatMap = npt.NDArray[np.float32]

class Matcher:
    """Matches rectified stereo pairs with the command line's options (see help(Matcher))."""

    def __init__(
        self,
        *,
        min_disparity: int = 0,
        max_disparity: Optional[int] = None,
        matcher: Literal["sgm", "bm"] = "sgm",
        preset: Literal["fast", "balanced", "accurate"] = "balanced",
        fill: bool = False,
        speckle_size: Optional[int] = None,
        edge_snap: Optional[int] = None,
        confidence: bool = False,
        min_confidence: Optional[float] = None,
        single_pass: bool = False,
        paths: Optional[Literal[4, 8]] = None,
        search: Optional[Literal["full", "hierarchical", "auto"]] = None,
        downscale: Union[int, Literal["auto", "coarse"], None] = None,
        p1: Optional[int] = None,
        p2: Optional[int] = None,
        uniqueness: Optional[int] = None,
        lr_max_diff: Optional[float] = None,
        lr_check: bool = True,
        subpixel: Optional[Literal["none", "parabola", "equiangular"]] = None,
        block_size: Optional[int] = None,
        bm_cost: Optional[Literal["census", "sad"]] = None,
        align: bool = True,
        rectification_check: Literal["every", "first"] = "every",
        max_memory: Optional[Union[int, str]] = None,
        max_pixels: Optional[Union[int, str]] = None,
        threads: Optional[int] = None,
    ) -> None: ...
    def compute(self, left: ImageInput, right: ImageInput) -> FloatMap:
        """Disparity of the left view: float32 (H, W), px, NaN where invalid. Releases the GIL."""
    def compute_detailed(self, left: ImageInput, right: ImageInput) -> DetailedResult:
        """Like compute, with confidence, the filled mask, timings and measurements."""
    @property
    def params(self) -> Dict[str, Any]:
        """The resolved matcher parameters."""

class DetailedResult:
    """What Matcher.compute_detailed returns."""

    @property
    def disparity(self) -> FloatMap: ...
    @property
    def confidence(self) -> Optional[FloatMap]: ...
    @property
    def filled(self) -> npt.NDArray[np.bool_]: ...
    @property
    def timings_ms(self) -> Dict[str, float]: ...
    @property
    def rectification(self) -> Dict[str, Any]: ...
    @property
    def adaptation(self) -> Optional[Dict[str, Any]]: ...
    @property
    def search(self) -> Optional[Dict[str, Any]]: ...
    @property
    def range(self) -> Tuple[int, int]: ...
    @property
    def copied(self) -> Tuple[bool, bool]: ...

class Rig:
    """A rectified stereo rig: baseline (mm) and focal length (px)."""

    def __init__(
        self,
        baseline_mm: float,
        *,
        focal_mm: Optional[float] = None,
        pixel_um: Optional[float] = None,
        focal_px: Optional[float] = None,
        doffs: float = 0.0,
        cx: Optional[float] = None,
        cy: Optional[float] = None,
    ) -> None: ...
    @staticmethod
    def from_calib(path: PathLike, *, baseline_mm: Optional[float] = None) -> Rig: ...
    @property
    def baseline_mm(self) -> float: ...
    @property
    def focal_px(self) -> float: ...
    @property
    def doffs(self) -> float: ...
    @property
    def principal_point(self) -> Optional[Tuple[float, float]]: ...
    @property
    def calib_size(self) -> Optional[Tuple[int, int]]: ...
    @property
    def ndisp(self) -> Optional[int]: ...
    def depth_at(self, disparity_px: float) -> Optional[float]: ...
    def disparity_at(self, distance_m: float) -> float: ...
    def depth(
        self, disparity: npt.NDArray[Any], *, min_depth: Optional[float] = None, max_depth: Optional[float] = None
    ) -> FloatMap:
        """Depth map, float32 (H, W) metres, NaN where invalid."""
    @overload
    def points(
        self,
        disparity: npt.NDArray[Any],
        *,
        step: int = 1,
        colors: None = None,
        min_depth: Optional[float] = None,
        max_depth: Optional[float] = None,
    ) -> FloatMap: ...
    @overload
    def points(
        self,
        disparity: npt.NDArray[Any],
        *,
        step: int = 1,
        colors: npt.NDArray[np.uint8],
        min_depth: Optional[float] = None,
        max_depth: Optional[float] = None,
    ) -> Tuple[FloatMap, npt.NDArray[np.uint8]]: ...

def calc(
    *,
    baseline_mm: float,
    focal_mm: float,
    pixel_um: float,
    doffs: float = 0.0,
    subpixel: float = 1.0,
    sensor_width_mm: Optional[float] = None,
    width_px: Optional[float] = None,
    max_disparity: Optional[float] = None,
    disparity_px: Optional[float] = None,
    distance_m: Optional[float] = None,
    table: bool = False,
    table_min: Optional[float] = None,
    table_max: Optional[float] = None,
    table_step: Optional[float] = None,
) -> Dict[str, Any]:
    """The rig design calculator (stereo-depth calc --json) as a dict."""

def read_pfm(path: PathLike) -> FloatMap: ...
def write_pfm(path: PathLike, map: FloatMap) -> None: ...
def write_exr(path: PathLike, depth: Optional[FloatMap] = None, *, channels: Optional[Dict[str, FloatMap]] = None) -> None: ...
@overload
def read_image(path: PathLike, mode: Literal["gray", "grey"] = "gray") -> npt.NDArray[np.uint16]: ...
@overload
def read_image(path: PathLike, mode: Literal["rgb"]) -> npt.NDArray[np.uint8]: ...
def write_ply(path: PathLike, points: FloatMap, colors: Optional[npt.NDArray[np.uint8]] = None) -> None: ...
