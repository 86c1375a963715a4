"""Comparison scenes and their runners (bpy side): scenes, renders, passes handed to core."""
