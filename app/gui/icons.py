"""viser's button icons read from one open zip file while the workbench is built.

viser 1.1 reads each icon (``_icons.svg_from_icon``) by opening its zip of about 5000 tabler
icons and parsing the zip's whole directory, again for each icon name: the workbench's 19 icons
took 0.8 s of its 1.4 s build, in every ``robomach serve`` start. Inside ``icons_from_one_zip()``
viser's two callers read the icons from one open zip; an icon read then is kept, and outside
it viser's own reader serves the others. The icons are the same bytes. With a viser that reads
its icons otherwise nothing is changed.
"""

from __future__ import annotations

import importlib
import logging
import threading
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

log = logging.getLogger(__name__)

_CALLERS = ("viser._gui_api", "viser._gui_handles")  # the modules that import svg_from_icon
_LOCK = threading.Lock()
_READ: dict[str, str] = {}  # icon name -> svg, read from the open zip
_OPEN: list[zipfile.ZipFile] = []  # the zip while a build is on


def _one_zip_reader(viser_reader: Callable[[str], str]) -> Callable[[str], str]:
    def svg_from_icon(icon_name: str) -> str:
        """The icon's ``<svg />`` text, as viser's ``svg_from_icon`` returns it."""
        with _LOCK:
            if icon_name not in _READ and _OPEN:
                _READ[icon_name] = _OPEN[0].read(f"{icon_name}.svg").decode("utf-8")
            svg = _READ.get(icon_name)
        return viser_reader(icon_name) if svg is None else svg

    svg_from_icon.viser_reader = viser_reader  # type: ignore[attr-defined]
    return svg_from_icon


@contextmanager
def icons_from_one_zip() -> Iterator[None]:
    """Within it viser reads its icons from one open zip (module docstring)."""
    try:
        icons = importlib.import_module("viser._icons")
        callers = [importlib.import_module(name) for name in _CALLERS]
    except ImportError:
        callers = []
    path = Path(getattr(icons, "ICONS_DIR", "") if callers else "") / "tabler-icons.zip"
    if not callers or not path.is_file() or not all(hasattr(m, "svg_from_icon") for m in callers):
        log.debug("viser reads its icons otherwise: left as it is")
        yield
        return
    for module in callers:
        reader = module.svg_from_icon
        if not hasattr(reader, "viser_reader"):
            module.svg_from_icon = _one_zip_reader(reader)  # type: ignore[attr-defined]
    with zipfile.ZipFile(path) as icons_zip:
        with _LOCK:
            _OPEN.append(icons_zip)
        try:
            yield
        finally:
            with _LOCK:
                _OPEN.remove(icons_zip)
