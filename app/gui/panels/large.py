"""Open a figure or a table large: a modal window as wide as the user's browser allows.

viser's own modals are as wide as the sidebar (Mantine's default size); a figure opened in
one is no bigger than its thumbnail. The modal here carries a style that widens it to 95 % of
the window while it is open (the style lives in the modal's own HTML, so it goes with it).
"""

from __future__ import annotations

import base64
from collections.abc import Callable
from typing import TYPE_CHECKING

import viser

if TYPE_CHECKING:
    from viser._gui_handles import GuiModalHandle  # not exported by viser

# Widen the modal this style sits in (and only while it is open).
WIDE_MODAL_STYLE = (
    "<style>.mantine-Modal-content, [class*='Modal-content'] "
    "{flex: 0 0 95vw !important; max-width: 95vw !important; width: 95vw !important}</style>"
)


def png_html(png: bytes, *, alt: str) -> str:
    """An <img> of the PNG at the modal's full width."""
    data = base64.b64encode(png).decode()
    return (
        f'<img alt="{alt}" src="data:image/png;base64,{data}" '
        'style="width:100%;height:auto;display:block">'
    )


def open_large(
    client: viser.ClientHandle,
    title: str,
    html: str,
    *,
    download: tuple[str, bytes] | None = None,
    on_close: Callable[[], None] | None = None,
) -> GuiModalHandle:
    """A wide modal holding ``html`` (a figure from ``png_html``, a table), with a download
    button for ``download`` (name, bytes) and a Close button."""
    gui = client.gui
    with gui.add_modal(title) as modal:
        gui.add_html(WIDE_MODAL_STYLE + html)
        if download is not None:
            name, data = download
            gui.add_button(f"Download {name}").on_click(
                lambda _: client.send_file_download(name, data)
            )

        def close(_) -> None:
            modal.close()
            if on_close is not None:
                on_close()

        gui.add_button("Close").on_click(close)
    return modal
