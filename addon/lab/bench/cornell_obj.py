"""The published Cornell box as a user brings it: the OBJ/MTL written out and imported with Blender's OBJ
importer (the radiosity benchmark's and tests' scene)."""
import os

import bpy

# Geometry: Cornell University Program of Computer Graphics, "Cornell Box Data"
# (http://www.graphics.cornell.edu/online/box/data.html), millimetres -> metres, Y up as published (the OBJ
# importer turns it to Z up): one unbroken ceiling quad and the light quad 1 mm below it (y = 547.8), as
# published. The boxes are open at the bottom as published (five faces each).
# Reflectances: RGB of the published spectra as used by the pbrt-v3 / Mitsuba Cornell scenes (white 0.725
# 0.71 0.68, red 0.63 0.065 0.05, green 0.14 0.45 0.091); light Ke 17 12 4 (radiance, W/m²/sr).
OBJ = """mtllib cbox.mtl
o Room
v 0.5528 0 0
v 0 0 0
v 0 0 0.5592
v 0.5496 0 0.5592
v 0.556 0.5488 0
v 0.556 0.5488 0.5592
v 0 0.5488 0.5592
v 0 0.5488 0
v 0.343 0.5478 0.227
v 0.343 0.5478 0.332
v 0.213 0.5478 0.332
v 0.213 0.5478 0.227
usemtl white
f 1 2 3 4
f 5 6 7 8
f 4 3 7 6
usemtl green
f 3 2 8 7
usemtl red
f 1 4 6 5
usemtl light
{light}
o ShortBlock
v 0.130 0.165 0.065
v 0.082 0.165 0.225
v 0.240 0.165 0.272
v 0.290 0.165 0.114
v 0.290 0 0.114
v 0.240 0 0.272
v 0.130 0 0.065
v 0.082 0 0.225
usemtl white
f 13 14 15 16
f 17 16 15 18
f 19 13 16 17
f 20 14 13 19
f 18 15 14 20
o TallBlock
v 0.423 0.330 0.247
v 0.265 0.330 0.296
v 0.314 0.330 0.456
v 0.472 0.330 0.406
v 0.423 0 0.247
v 0.472 0 0.406
v 0.314 0 0.456
v 0.265 0 0.296
usemtl white
f 21 22 23 24
f 25 21 24 26
f 26 24 23 27
f 27 23 22 28
f 28 22 21 25
"""
MTL = """newmtl white
Kd 0.725 0.71 0.68
Ks 0 0 0
illum 1
newmtl green
Kd 0.14 0.45 0.091
Ks 0 0 0
illum 1
newmtl red
Kd 0.63 0.065 0.05
Ks 0 0 0
illum 1
newmtl light
Kd 0.78 0.78 0.78
Ke 17 12 4
Ks 0 0 0
illum 1
"""
LIGHT_DOWN, LIGHT_UP = "f 9 10 11 12", "f 12 11 10 9"


def import_cornell(folder, light=LIGHT_DOWN):
    """Write the OBJ/MTL and import them with Blender's OBJ importer into the current (empty) scene."""
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "cbox.obj"), "w") as f:
        f.write(OBJ.replace("{light}", light))
    with open(os.path.join(folder, "cbox.mtl"), "w") as f:
        f.write(MTL)
    bpy.ops.wm.obj_import(filepath=os.path.join(folder, "cbox.obj"))
    return bpy.context.scene
