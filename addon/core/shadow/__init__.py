"""Shadows in numpy: the methods the shadow lab compares and the measures it compares them with.

planar     projected planar shadows (Blinn 1988) onto a receiver plane
depth_map  shadow maps (Williams 1978): depth maps, bias, PCF
volume     shadow volumes (Crow 1977), z-pass and z-fail counts
raster     screen-space helpers: clipping, pixel spans, a depth-tested triangle rasteriser
metrics    agreement with a ray-traced reference: confusion counts and images
"""
