"""Illumination Lab extension entry: the package lives in addon/."""
from .addon import register, unregister  # noqa: F401
