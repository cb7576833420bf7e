"""Mitsuba 3 as an independent reference renderer (optional: ``pip install 'lightcuts[mitsuba]'``).

A stage above ``report`` and below the commands: :mod:`.export` turns a lightcuts Scene, its camera,
sun and environment map into a Mitsuba scene dict; :mod:`.render` renders it
(:func:`~lightcuts.mitsuba.render.render_mitsuba`, :func:`~lightcuts.mitsuba.render.spp_for_seconds`).
Nothing here imports Mitsuba at import time; :func:`load_mitsuba` imports it on first use and
selects :data:`VARIANT`.
"""

from __future__ import annotations

from lightcuts.errors import LightcutsError

#: The Mitsuba variant: CPU, RGB, no LLVM needed (``llvm_ad_rgb`` needs libLLVM >= 16 at run time).
VARIANT = "scalar_rgb"
#: How to install the extra, quoted in the error when Mitsuba cannot be imported.
INSTALL_HINT = "pip install 'lightcuts[mitsuba]'"


def load_mitsuba():
    """The ``mitsuba`` module with :data:`VARIANT` set; LightcutsError (one line ending with the
    install command) if it cannot be imported or lacks the variant."""
    try:
        import mitsuba as mi
    except Exception as exc:  # ImportError, or a broken install failing inside its own import
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise LightcutsError(f"mitsuba: Mitsuba 3 cannot be imported ({why}); install it with: "
                             f"{INSTALL_HINT}") from None
    try:
        if mi.variant() != VARIANT:
            mi.set_variant(VARIANT)
    except Exception as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise LightcutsError(f"mitsuba: variant {VARIANT!r} unavailable ({why}); reinstall it with: "
                             f"{INSTALL_HINT}") from None
    mi.set_log_level(mi.LogLevel.Error)
    return mi
