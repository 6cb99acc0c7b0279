"""Type stubs of the native module ``uwnr._uwnr`` (PyO3). Pixels cross as
``(bytes, height, width, channels, dtype)`` with dtype ``"uint8"`` or ``"float32"``; use the
Python API in ``uwnr`` rather than this module."""

from typing import List, Optional, Tuple

Pixels = Tuple[bytes, int, int, int, str]

__version__: str
BUNDLED_MODEL: bool
BUNDLED_GAN: bool
DEVICES: List[str]
METHODS: List[str]

class Error(Exception):
    """A weights, model or rendering problem in uwnr."""

class NativeReference:
    def __init__(self, pixels: Pixels) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    def light_field(self, map: str) -> bytes: ...
    def pixels(self) -> bytes: ...

class NativeRenderer:
    def __init__(
        self,
        method: str,
        weights: Optional[str],
        options_json: str,
        seed: int,
        device: str,
        max_whole_pixels: int,
        tile: int,
        overlap: int,
    ) -> None: ...
    @property
    def method(self) -> str: ...
    @property
    def source(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def reference_use(self) -> str: ...
    @property
    def light_field_map(self) -> Optional[str]: ...
    def render(
        self,
        clean: Pixels,
        reference: Optional[NativeReference],
        depth: Optional[Pixels],
        depth_unit: str,
        seed: Optional[int],
        index: int,
    ) -> bytes: ...
    def render_batch(
        self,
        items: List[Tuple[Pixels, Optional[NativeReference], Optional[Pixels]]],
        depth_unit: str,
        seed: Optional[int],
    ) -> List[bytes]: ...

def builtin_depth(clean: Pixels) -> bytes: ...
def metric(name: str, pred: Pixels, target: Optional[Pixels], gray: bool) -> float: ...
def load_rgb(path: str) -> Tuple[bytes, int, int]: ...
