"""User-facing errors: one line that names the file or key and what is wrong."""


class LightcutsError(Exception):
    """An error caused by the user's input (a config, a mesh, a light or tree file, a name).

    The CLI prints ``error: <message>`` on one line and exits with status 2; never a traceback.
    Messages start with the file or key at fault, e.g. ``configs/x.yaml: render.eps: ...``.
    """

    def __init__(self, message="", *args):
        # One line whatever the input it names: a file name or a value with a line break or another
        # control character is shown escaped (\n, \x1b), as repr shows it.
        if isinstance(message, str) and any(c < " " or c == "\x7f" for c in message):
            message = "".join(repr(c)[1:-1] if (c < " " or c == "\x7f") else c for c in message)
        super().__init__(message, *args)
