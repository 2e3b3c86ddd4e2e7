"""Can PyBullet's GUI open a window here? Checked before connecting, because a failed GUI connect
ends the whole Python process ("cannot connect to X server") instead of raising."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

_HINT = (
    'render_mode="human" opens PyBullet\'s GUI window, which needs a display. Run under a virtual '
    'display (xvfb-run -a python ...), or use render_mode="rgb_array" (offscreen chase view) or None'
)


def require_gui_display() -> None:
    """Raise RuntimeError unless PyBullet's GUI can open a window.

    On Linux PyBullet's GUI is an X11 (GLX) window: ``DISPLAY`` must be set (a Wayland session
    provides one through XWayland) and the X server must accept a connection, which is tried here
    with Xlib's ``XOpenDisplay`` when libX11 is installed (PyBullet loads the same library).
    Other platforms are not checked.
    """
    if not sys.platform.startswith("linux"):
        return
    display = os.environ.get("DISPLAY", "")
    if not display:
        if os.environ.get("WAYLAND_DISPLAY"):
            raise RuntimeError(
                f"{_HINT}. WAYLAND_DISPLAY is set but DISPLAY is not: PyBullet's GUI is X11-only "
                "and needs XWayland (DISPLAY)"
            )
        raise RuntimeError(f"{_HINT}. No display here: DISPLAY (and WAYLAND_DISPLAY) unset")
    name = ctypes.util.find_library("X11") or "libX11.so.6"
    try:
        xlib = ctypes.CDLL(name)
    except OSError as e:
        raise RuntimeError(f"{_HINT}. PyBullet's GUI needs libX11 ({name}: {e})") from None
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    handle = xlib.XOpenDisplay(display.encode())
    if not handle:
        raise RuntimeError(f"{_HINT}. Cannot connect to the X server of DISPLAY={display!r}")
    xlib.XCloseDisplay(handle)


__all__ = [
    "require_gui_display",
]
