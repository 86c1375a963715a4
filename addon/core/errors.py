"""Domain exceptions: raised by core and adapters, turned into reports at the boundary.

An operator reports ``str(error)`` and cancels; a script prints it as one line and
exits 2 for :class:`InputError`, 1 for any other :class:`ILError`.
"""


class ILError(Exception):
    """A failure the user can understand from its message alone."""


class InputError(ILError):
    """Bad input: an unknown name, a value out of range, a missing object or file."""


#: What a script or an operator says when a job runs out of memory (its one line on stderr / ERROR report).
OUT_OF_MEMORY = "out of memory: use smaller sizes or fewer samples"


def os_error_message(error):
    """The one line a script or an operator gives for an OSError (a full disk, a missing folder)."""
    return f"{error.strerror or error}" + (f": {error.filename}" if error.filename else "")


class ILWarning(UserWarning):
    """Something the user should know that does not stop the job (an object skipped, a setting
    ignored). Scripts print it as one ``warning:`` line; operators report it as a WARNING."""


def warn(message):
    """Emit ``message`` as an :class:`ILWarning` (shown at the script or operator boundary)."""
    import warnings
    warnings.warn(ILWarning(message), stacklevel=2)
