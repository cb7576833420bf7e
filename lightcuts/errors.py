"""User-facing errors: one line that names the file or key and what is wrong."""


class LightcutsError(Exception):
    """An error caused by the user's input (a config, a mesh, a light or tree file, a name).

    The CLI prints ``error: <message>`` on one line and exits with status 2; never a traceback.
    Messages start with the file or key at fault, e.g. ``configs/x.yaml: render.eps: ...``.
    """
