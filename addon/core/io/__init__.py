"""Files in and out, numpy only.

files  atomic writes, JSON, checked output folders
exr    OpenEXR read and write (float channels)
hdr    Radiance RGBE (.hdr) read and write
png    PNG encode and decode, sRGB and tone mapping for previews
"""
