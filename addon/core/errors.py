"""Domain exceptions: raised by core and adapters, turned into reports at the boundary.

An operator reports ``str(error)`` and cancels; a script prints it as one line and
exits 2 for :class:`InputError`, 1 for any other :class:`ILError`.
"""


class ILError(Exception):
    """A failure the user can understand from its message alone."""


class InputError(ILError):
    """Bad input: an unknown name, a value out of range, a missing object or file."""


class ILWarning(UserWarning):
    """Something the user should know that does not stop the job (an object skipped, a setting
    ignored). Scripts print it as one ``warning:`` line; operators report it as a WARNING."""


def warn(message):
    """Emit ``message`` as an :class:`ILWarning` (shown at the script or operator boundary)."""
    import warnings
    warnings.warn(ILWarning(message), stacklevel=2)
