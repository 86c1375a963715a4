"""Light-map pipeline on Cycles (bpy side): UVs, temporary materials, bakes, restore."""
