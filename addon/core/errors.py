"""Domain exceptions: raised by core and adapters, turned into reports at the boundary.

An operator reports ``str(error)`` and cancels; a script prints it as one line and
exits 2 for :class:`InputError`, 1 for any other :class:`ILError`.
"""


class ILError(Exception):
    """A failure the user can understand from its message alone."""


class InputError(ILError):
    """Bad input: an unknown name, a value out of range, a missing object or file."""
