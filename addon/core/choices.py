"""Names picked from a fixed set (methods of a lab, maps of a bake): one parser, one message."""
from .errors import InputError


def parse_choices(value, allowed, what):
    """``"a,b"`` or ``["a", "b"]`` -> the names in the given order, duplicates dropped.

    Raises InputError naming the first unknown one and the choices ("unknown <what> 'x' (choose
    from ...)"), or when nothing is given.
    """
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",")]
    out = []
    for v in value:
        if not v:
            continue
        if v not in allowed:
            raise InputError(f"unknown {what} '{v}' (choose from {', '.join(allowed)})")
        if v not in out:
            out.append(v)
    if not out:
        raise InputError(f"no {what} given (choose from {', '.join(allowed)})")
    return out
