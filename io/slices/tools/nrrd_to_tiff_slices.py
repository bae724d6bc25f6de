#!/usr/bin/env python3
"""Writes a 3D NRRD volume as a folder of single-page TIFF slices (numpy only).

Usage: nrrd_to_tiff_slices.py VOLUME.nrrd OUT_FOLDER

One uncompressed TIFF per z slice (slice_0000.tif, ...), the volume's own
sample type (u8 i8 u16 i16 i32 f32 f64, SampleFormat set), column = x,
row = y, no flips, and ImageJ metadata carrying the spacing (resolution tags
for x and y, "spacing=" for z) so that `isomend info OUT_FOLDER` reports it.
Reads NRRD with attached raw or gzip data, "sizes", "type", "endian",
"spacings" or axis-aligned "space directions" (the length of each vector).
Used by scripts/demo.sh; handy for making test stacks from any NRRD.
"""
import gzip
import os
import struct
import sys

import numpy as np

TYPES = {"uchar": "u1", "unsigned char": "u1", "uint8": "u1", "uint8_t": "u1",
         "signed char": "i1", "int8": "i1", "int8_t": "i1",
         "short": "i2", "int16": "i2", "int16_t": "i2", "signed short": "i2",
         "ushort": "u2", "unsigned short": "u2", "uint16": "u2", "uint16_t": "u2",
         "int": "i4", "int32": "i4", "int32_t": "i4", "float": "f4", "double": "f8"}


def read_nrrd(path):
    data = open(path, "rb").read()
    head, body = data.split(b"\n\n", 1)
    fields = {}
    for line in head.decode("latin-1").splitlines()[1:]:
        if line.startswith("#") or ": " not in line:
            continue
        k, v = line.split(": ", 1)
        fields[k.strip().lower()] = v.strip()
    sizes = [int(s) for s in fields["sizes"].split()]
    if len(sizes) != 3:
        sys.exit("%s: not a 3D volume (sizes: %s)" % (path, fields["sizes"]))
    code = TYPES.get(fields["type"].lower())
    if not code:
        sys.exit("%s: unsupported type '%s'" % (path, fields["type"]))
    order = ">" if fields.get("endian", "little") == "big" else "<"
    enc = fields.get("encoding", "raw")
    if enc in ("gzip", "gz"):
        body = gzip.decompress(body)
    elif enc != "raw":
        sys.exit("%s: unsupported encoding '%s'" % (path, enc))
    vol = np.frombuffer(body, order + code, count=sizes[0] * sizes[1] * sizes[2])
    vol = vol.reshape(sizes[2], sizes[1], sizes[0]).astype(np.dtype(code).newbyteorder("<"))
    spacing = [1.0, 1.0, 1.0]
    if "spacings" in fields:
        spacing = [abs(float(s)) for s in fields["spacings"].split()]
    elif "space directions" in fields:
        vecs = fields["space directions"].replace(")", "").split("(")[1:]
        spacing = [float(np.linalg.norm([float(c) for c in v.split(",")])) for v in vecs]
    return vol, spacing


def write_tiff(path, img, spacing):
    """Minimal little-endian, uncompressed, single-strip TIFF with ImageJ metadata."""
    h, w = img.shape
    fmt = {"u": 1, "i": 2, "f": 3}[img.dtype.kind]
    desc = ("ImageJ=1.11a\nunit=mm\nspacing=%r\n" % spacing[2]).encode() + b"\0"
    pix = np.ascontiguousarray(img).astype(img.dtype.newbyteorder("<")).tobytes()
    n = 13                                   # IFD entries, in tag order
    xres_at = 8 + 2 + n * 12 + 4             # after the header and the IFD
    yres_at, desc_at = xres_at + 8, xres_at + 16
    pix_at = desc_at + len(desc)
    entries = [
        (256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, img.dtype.itemsize * 8), (259, 3, 1, 1),
        (262, 3, 1, 1), (270, 2, len(desc), desc_at), (273, 4, 1, pix_at), (278, 4, 1, h),
        (279, 4, 1, len(pix)), (282, 5, 1, xres_at), (283, 5, 1, yres_at),
        (296, 3, 1, 1),                      # ResolutionUnit none: ImageJ's pixels per unit
        (339, 3, 1, fmt),                    # SampleFormat
    ]
    assert len(entries) == n
    out = bytearray(b"II*\0" + struct.pack("<IH", 8, n))
    for tag, typ, count, value in entries:
        if typ == 3 and count == 1:
            out += struct.pack("<HHIHH", tag, typ, count, value, 0)
        else:
            out += struct.pack("<HHII", tag, typ, count, value)
    out += struct.pack("<I", 0)
    one = 1000000                            # pixels per unit = 1e6 / (spacing * 1e6)
    out += struct.pack("<IIII", one, int(round(spacing[0] * one)), one, int(round(spacing[1] * one)))
    out += desc + pix
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(out)
    os.replace(tmp, path)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    vol, spacing = read_nrrd(sys.argv[1])
    os.makedirs(sys.argv[2], exist_ok=True)
    for k in range(vol.shape[0]):
        write_tiff(os.path.join(sys.argv[2], "slice_%04d.tif" % k), vol[k], spacing)
    print("%s: %d slices of %dx%d %s, spacing %s -> %s" % (sys.argv[1], vol.shape[0], vol.shape[2],
          vol.shape[1], vol.dtype.name, ",".join("%g" % s for s in spacing), sys.argv[2]))


if __name__ == "__main__":
    main()
