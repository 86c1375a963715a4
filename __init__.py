"""Illumination Lab extension entry: the package lives in addon/. Imported outside a package (pytest's collection of a
checkout whose folder name is not an identifier, e.g. ``illumination-lab`` or ``tmp.Xy12``) it registers nothing."""
if __package__:
    from .addon import register, unregister  # noqa: F401
