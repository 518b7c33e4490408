"""viser's icons read from one open zip while the workbench is built (``app.gui.icons``): the
buttons get the same svg as viser's own reader gives, inside the build and after it."""

from __future__ import annotations

import viser._gui_api as gui_api
import viser._icons as viser_icons

from app.gui.icons import icons_from_one_zip

NAMES = ("hand-stop", "player-play", "download", "trash", "arrow-back-up")


def test_the_icons_read_from_one_zip_are_viser_own(server) -> None:
    with icons_from_one_zip():
        buttons = [server.gui.add_button(name, icon=name) for name in NAMES]
        inside = [gui_api.svg_from_icon(name) for name in NAMES]
    assert inside == [viser_icons.svg_from_icon(name) for name in NAMES]
    assert [b._icon_html for b in buttons] == inside
    # After the build an icon not read yet comes from viser's own reader.
    assert gui_api.svg_from_icon("robot") == viser_icons.svg_from_icon("robot")
    with icons_from_one_zip():  # a second build keeps the same reader
        assert gui_api.svg_from_icon("download") == inside[2]
