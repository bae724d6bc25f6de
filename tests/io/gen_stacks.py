#!/usr/bin/env python3
"""Writes the test stacks of tests/io into OUTDIR and a manifest for the C test.

Every stack is written here, by the test, with OpenImageIO's Python bindings or
tifffile (an independent TIFF writer); the expected volume of each good case is
written next to it as little-endian raw (x fastest, then y, then z), computed
with numpy from the same arrays, so the C test compares what isomend_io reads
with what was meant, sample by sample.

manifest.tsv (the OpenImageIO build of isomend_io) and manifest_portable.tsv
(the portable build on libtiff/OpenEXR/libpng), one case per line,
tab-separated; the two differ only where a build's image library differs
(a case given with only="oiio" or only="portable"):
  ok   NAME TYPE NX NY NZ EXPECTED.raw KIND CHANNEL FIRST COUNT STEP SX SY SZ SPSRC SOURCE...
  err  NAME STATUS MESSAGE-SUBSTRING CHANNEL FIRST COUNT STEP SOURCE...
CHANNEL: -1 auto, -2 luma, else index.  SX SY SZ: expected spacing (0 0 0 =
not checked); SPSRC: expected spacing sources "x,y,z" names or "-".  STATUS is
an isomend_io_status number.  SOURCE paths are relative to OUTDIR.

Usage: gen_stacks.py OUTDIR
"""
import os
import shutil
import struct
import sys

import numpy as np
import OpenImageIO as oiio
import tifffile

OUT = os.path.abspath(sys.argv[1])
shutil.rmtree(OUT, ignore_errors=True)  # stale files would change folder contents
os.makedirs(OUT)
RNG = np.random.default_rng(20261122)
LINES = []

# isomend_io_status values (isomend_io.h)
NOT_FOUND, UNREADABLE, CORRUPT, MISMATCH, UNSUPPORTED, TOO_FEW, TOO_LARGE = 2, 3, 4, 5, 6, 7, 8
AUTO, LUMA = -1, -2


def d(*parts):
    p = os.path.join(OUT, *parts)
    os.makedirs(p, exist_ok=True)
    return p


def oiio_write(path, img, fmt, compression="none", channels=None, extra=None, bits=None):
    """img: (h, w) or (h, w, c) array already in the stored representation."""
    if img.ndim == 2:
        img = img[:, :, None]
    h, w, c = img.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    if compression:
        spec.attribute("compression", compression)
    if channels:
        spec.channelnames = tuple(channels)
    if bits:
        spec.attribute("oiio:BitsPerSample", bits)
    for k, v in (extra or {}).items():
        spec.attribute(k, v)
    out = oiio.ImageOutput.create(path)
    assert out is not None and out.open(path, spec), oiio.geterror()
    assert out.write_image(np.ascontiguousarray(img)), out.geterror()
    out.close()


def save_expected(name, vol):
    """vol indexed [z, y, x] in the delivered type."""
    p = os.path.join(OUT, name + ".expected.raw")
    np.ascontiguousarray(vol).astype(vol.dtype.newbyteorder("<")).tofile(p)
    return os.path.basename(p)


def ok(name, tname, vol, kind, sources, channel=AUTO, first=0, count=0, step=1,
       spacing=(0, 0, 0), spsrc="-", only=None):
    nz, ny, nx = vol.shape
    exp = save_expected(name, vol)
    rel = [os.path.relpath(s, OUT) for s in sources]
    LINES.append((only, "\t".join(["ok", name, tname, str(nx), str(ny), str(nz), exp, kind, str(channel),
                            str(first), str(count), str(step)] + ["%.17g" % s for s in spacing] +
                           [spsrc] + rel)))


def err(name, status, substring, sources, channel=AUTO, first=0, count=0, step=1, only=None):
    rel = [os.path.relpath(s, OUT) if os.path.isabs(s) else s for s in sources]
    LINES.append((only, "\t".join(["err", name, str(status), substring, str(channel), str(first),
                                   str(count), str(step)] + rel)))


def rand(shape, dtype, lo, hi):
    return RNG.integers(lo, hi, size=shape, endpoint=True).astype(dtype)


NX, NY = 13, 9   # odd, unequal: a transposition or a row stride error shows

# ---- good stacks -----------------------------------------------------------------------------

# u8 folder, natural order (s_2 before s_10), distractors of other extensions ignored
f = d("u8_folder")
vol = rand((12, NY, NX), np.uint8, 0, 255)
vol[:, 0, 0] = np.arange(12)            # slice index in a corner
for k in range(12):
    oiio_write(os.path.join(f, "s_%d.tif" % (k + 1)), vol[k], "uint8")
oiio_write(os.path.join(f, "preview.png"), vol[0], "uint8")
open(os.path.join(f, "notes.txt"), "w").write("not an image\n")
open(os.path.join(f, ".hidden.tif"), "w").write("hidden files are skipped\n")
ok("u8_folder", "u8", vol, "folder", [f])

# u16 printf pattern with first/count/step (deflate)
f = d("u16_pattern")
allv = rand((13, NY, NX), np.uint16, 0, 65535)
for k in range(13):
    oiio_write(os.path.join(f, "slice_%04d.tif" % k), allv[k], "uint16", "zip")
ok("u16_pattern", "u16", allv[3:11:2], "pattern", [os.path.join(f, "slice_%04d.tif")],
   first=3, count=4, step=2)
ok("u16_pattern_all", "u16", allv, "pattern", [os.path.join(f, "slice_%04d.tif")])

# i16 glob, negative values kept, natural order of g_9, g_10, g_100; h_* not matched
f = d("i16_glob")
vol = rand((3, NY, NX), np.int16, -32768, 32767)
vol[:, 0, 0] = [-1000, -2000, -3000]
for k, idx in enumerate([9, 10, 100]):
    tifffile.imwrite(os.path.join(f, "g_%d.tif" % idx), vol[k], photometric="minisblack")
tifffile.imwrite(os.path.join(f, "h_1.tif"), vol[0], photometric="minisblack")
ok("i16_glob", "i16", vol, "glob", [os.path.join(f, "g_*.tif")])

# f32 explicit list: the order given is kept (not sorted)
f = d("f32_list")
vol = RNG.normal(0, 1000, size=(4, NY, NX)).astype(np.float32)
names = ["c.tif", "a.tif", "d.tif", "b.tif"]
for k, n in enumerate(names):
    oiio_write(os.path.join(f, n), vol[k], "float", "zip")
ok("f32_list", "f32", vol, "list", [os.path.join(f, n) for n in names])

# packed 12-bit TIFF: stored values 0..4095 (OIIO's writer takes them scaled to 16 bits)
f = d("u12_folder")
vol = rand((3, NY, NX), np.uint16, 0, 4095)
vol[0, 0, :3] = [0, 4095, 1]
for k in range(3):
    oiio_write(os.path.join(f, "t_%02d.tif" % k), vol[k] << 4, "uint16", "none", bits=12)
ok("u12_folder", "u16", vol, "folder", [f])

# 1-bit and 4-bit TIFF with an explicit BitsPerSample (OIIO's writer takes them scaled to 8 bits)
for bits in (1, 4):
    f = d("u%dbit" % bits)
    vol = rand((3, NY, NX), np.uint8, 0, (1 << bits) - 1)
    for k in range(3):
        oiio_write(os.path.join(f, "b%d.tif" % k), vol[k] * (255 // ((1 << bits) - 1)), "uint8", "none",
                   bits=bits)
    ok("u%dbit" % bits, "u8", vol, "folder", [f])

# OpenEXR half (values beyond 1 and negative) and float
f = d("exr_half")
vol = (RNG.normal(0, 300, size=(3, NY, NX))).astype(np.float16)
for k in range(3):
    oiio_write(os.path.join(f, "e%d.exr" % k), vol[k], "half", "zip", channels=["Y"])
ok("exr_half", "f32", vol.astype(np.float32), "folder", [f])
f = d("exr_float")
vol = (RNG.normal(0, 1e5, size=(3, NY, NX))).astype(np.float32)
for k in range(3):
    oiio_write(os.path.join(f, "e%d.exr" % k), vol[k], "float", "piz", channels=["Y"])
ok("exr_float", "f32", vol, "folder", [f])

# multi-part EXR: parts are slices
f = d("exr_multipart")
vol = (RNG.normal(0, 10, size=(4, NY, NX))).astype(np.float16)
specs = []
for k in range(4):
    s = oiio.ImageSpec(NX, NY, 1, "half")
    s.channelnames = ("Y",)
    s.attribute("name", "slice%d" % k)
    specs.append(s)
p = os.path.join(f, "stack.exr")
out = oiio.ImageOutput.create(p)
assert out.open(p, specs), out.geterror()
for k in range(4):
    if k:
        assert out.open(p, specs[k], "AppendSubimage"), out.geterror()
    assert out.write_image(np.ascontiguousarray(vol[k][:, :, None])), out.geterror()
out.close()
ok("exr_multipart", "f32", vol.astype(np.float32), "multipage", [p])

# multi-page TIFF written by tifffile in ImageJ's format: spacing from metadata
f = d("multipage")
vol = rand((5, NY, NX), np.uint16, 0, 60000)
p = os.path.join(f, "stack.tif")
tifffile.imwrite(p, vol, imagej=True, resolution=(1 / 0.25, 1 / 0.5),
                 metadata={"spacing": 2.5, "unit": "um", "axes": "ZYX"})
ok("multipage_imagej", "u16", vol, "multipage", [p], spacing=(0.25, 0.5, 2.5),
   spsrc="imagej,imagej,imagej")

# TIFF resolution tags in pixels per cm: spacing in mm
f = d("res_cm")
vol = rand((2, NY, NX), np.uint8, 0, 255)
for k in range(2):
    tifffile.imwrite(os.path.join(f, "r%d.tif" % k), vol[k], photometric="minisblack",
                     resolution=(20.0, 40.0), resolutionunit="CENTIMETER")
ok("res_cm", "u8", vol, "folder", [f], spacing=(0.5, 0.25, 1.0), spsrc="tiff,tiff,default")

# PNG u8 and u16
for tname, dt, fmt, hi in (("u8", np.uint8, "uint8", 255), ("u16", np.uint16, "uint16", 65535)):
    f = d("png_" + tname)
    vol = rand((3, NY, NX), dt, 0, hi)
    for k in range(3):
        oiio_write(os.path.join(f, "p%d.png" % k), vol[k], fmt, None)
    ok("png_" + tname, tname, vol, "folder", [f])

# RGB: --channel 1 and --channel luma (Rec. 709 of the stored values, f32)
f = d("rgb")
rgb = rand((3, NY, NX, 3), np.uint8, 0, 255)
for k in range(3):
    oiio_write(os.path.join(f, "c%d.tif" % k), rgb[k], "uint8")
ok("rgb_channel1", "u8", rgb[..., 1], "folder", [f], channel=1)
r, g, b = (rgb[..., i].astype(np.float64) for i in range(3))
ok("rgb_luma", "f32", (0.2126 * r + 0.7152 * g + 0.0722 * b).astype(np.float32), "folder", [f],
   channel=LUMA)

# bimodal u8 (two classes around 20 and 200): Otsu's level lies between them
f = d("bimodal")
vol = rand((4, NY, NX), np.uint8, 17, 23)
mask = RNG.random((4, NY, NX)) < 0.4
vol[mask] = rand((int(mask.sum()),), np.uint8, 197, 203)
for k in range(4):
    oiio_write(os.path.join(f, "m%d.tif" % k), vol[k], "uint8")
ok("bimodal", "u8", vol, "folder", [f])

# the "L" phantom (tifffile, rows top to bottom as any viewer shows them): a vertical bar at
# columns 2-3 from row 2 down to row 12, a foot at rows 11-12 to the right up to column 9, in
# slices 1 and 2 of 4; slice 1 also has a 2x2 dot at columns 8-9, rows 2-3 (top right).
f = d("L_phantom")
vol = np.zeros((4, 16, 12), np.uint8)
for z in (1, 2):
    vol[z, 2:13, 2:4] = 100
    vol[z, 11:13, 2:10] = 100
vol[1, 2:4, 8:10] = 100
for k in range(4):
    tifffile.imwrite(os.path.join(f, "L_%d.tif" % k), vol[k], photometric="minisblack")
ok("L_phantom", "u8", vol, "folder", [f])

# NRRD (attached raw, little endian): isomend_io opens it through io/common's reader
f = d("nrrd")
vol = rand((5, NY, NX), np.uint16, 0, 65535)
with open(os.path.join(f, "vol.nrrd"), "wb") as fh:
    fh.write(("NRRD0004\ntype: uint16\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n"
              "endian: little\nspacings: 0.5 0.75 2\n\n" % (NX, NY, 5)).encode())
    fh.write(np.ascontiguousarray(vol).astype("<u2").tobytes())
ok("nrrd", "u16", vol, "nrrd", [os.path.join(f, "vol.nrrd")], spacing=(0.5, 0.75, 2.0),
   spsrc="header,header,header")
import gzip
with open(os.path.join(f, "vol_gz.nrrd"), "wb") as fh:
    fh.write(("NRRD0004\ntype: short\ndimension: 3\nsizes: %d %d %d\nencoding: gzip\n"
              "endian: big\n\n" % (NX, NY, 5)).encode())
    vol = rand((5, NY, NX), np.int16, -32768, 32767)
    fh.write(gzip.compress(np.ascontiguousarray(vol).astype(">i2").tobytes()))
ok("nrrd_gzip_be", "i16", vol, "nrrd", [os.path.join(f, "vol_gz.nrrd")])
# NRRD with x and y pointing backwards (RAS data from NIfTI): delivered reversed along them
vol = rand((4, NY, NX), np.uint8, 0, 255)
with open(os.path.join(f, "neg.nrrd"), "wb") as fh:
    fh.write(("NRRD0004\ntype: uchar\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n"
              "space: right-anterior-superior\nspace directions: (-0.5,0,0) (0,-0.75,0) (0,0,2)\n"
              "space origin: (10,20,30)\n\n" % (NX, NY, 4)).encode())
    fh.write(np.ascontiguousarray(vol).tobytes())
ok("nrrd_negative_axes", "u8", np.ascontiguousarray(vol[:, ::-1, ::-1]), "nrrd", [os.path.join(f, "neg.nrrd")],
   spacing=(0.5, 0.75, 2.0), spsrc="header,header,header")

# long stacks (headers are then checked by several threads): 150 files, 200 pages
f = d("many")
vol = rand((150, NY, NX), np.uint8, 0, 255)
for k in range(150):
    tifffile.imwrite(os.path.join(f, "m_%03d.tif" % k), vol[k], photometric="minisblack")
ok("many_files", "u8", vol, "folder", [f])
f = d("many_pages")
vol = rand((200, NY, NX), np.uint16, 0, 65535)
tifffile.imwrite(os.path.join(f, "pages.tif"), vol, photometric="minisblack")
ok("many_pages", "u16", vol, "multipage", [os.path.join(f, "pages.tif")])
# pages are opened directly at their IFD (a patched header): big-endian and BigTIFF layouts
vol = rand((70, NY, NX), np.int16, -32768, 32767)
tifffile.imwrite(os.path.join(f, "pages_be.tif"), vol, photometric="minisblack", byteorder=">")
ok("many_pages_be", "i16", vol, "multipage", [os.path.join(f, "pages_be.tif")])
vol = rand((70, NY, NX), np.uint8, 0, 255)
tifffile.imwrite(os.path.join(f, "pages_big.tif"), vol, photometric="minisblack", bigtiff=True)
ok("many_pages_bigtiff", "u8", vol, "multipage", [os.path.join(f, "pages_big.tif")])

# ---- more encodings: each read the same by both builds of isomend_io --------------------------

def png_write(path, rows, width, depth, colour, chunks=b""):
    """A PNG written here, byte by byte (rows: the filtered-free scanline bytes)."""
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, len(rows), depth, colour, 0, 0, 0)
    data = zlib.compress(b"".join(b"\x00" + r for r in rows))
    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunks + chunk(b"IDAT", data) +
                 chunk(b"IEND", b""))


def png_chunk(kind, data):
    import zlib
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def pack_bits(values, bits):
    """A row of samples packed most significant bit first (TIFF and PNG)."""
    acc, n, out = 0, 0, bytearray()
    for v in values:
        acc = (acc << bits) | int(v)
        n += bits
        while n >= 8:
            n -= 8
            out.append((acc >> n) & 0xFF)
    if n:
        out.append((acc << (8 - n)) & 0xFF)
    return bytes(out)


# grey PNG of 1, 2 and 4 bits: the stored values (0..15), as for TIFF; pHYs in pixels per metre
for bits in (1, 2, 4):
    f = d("png_%dbit" % bits)
    vol = rand((3, NY, NX), np.uint8, 0, (1 << bits) - 1)
    for k in range(3):
        png_write(os.path.join(f, "p%d.png" % k), [pack_bits(r, bits) for r in vol[k]], NX, bits, 0,
                  png_chunk(b"pHYs", struct.pack(">IIB", 2000, 4000, 1)))
    ok("png_%dbit" % bits, "u8", vol, "folder", [f], spacing=(0.5, 0.25, 1.0), spsrc="tiff,tiff,default")

# grey PNG with a tRNS chunk: grey and alpha (the grey is channel 0); palette PNG: R, G, B
f = d("png_trns")
vol = rand((2, NY, NX), np.uint8, 0, 255)
for k in range(2):
    png_write(os.path.join(f, "t%d.png" % k), [bytes(r) for r in vol[k]], NX, 8, 0,
              png_chunk(b"tRNS", struct.pack(">H", 7)))
ok("png_trns", "u8", vol, "folder", [f], channel=0)
f = d("png_palette")
palette = rand((16, 3), np.uint8, 0, 255)
idx = rand((2, NY, NX), np.uint8, 0, 15)
for k in range(2):
    png_write(os.path.join(f, "c%d.png" % k), [bytes(r) for r in idx[k]], NX, 8, 3,
              png_chunk(b"PLTE", palette.tobytes()))
ok("png_palette_g", "u8", palette[idx][..., 1], "folder", [f], channel=1)

# 16-bit RGBA PNG, channel 3 (alpha); an oFFs origin (pixels)
f = d("png_rgba16")
rgba = rand((2, NY, NX, 4), np.uint16, 0, 65535)
for k in range(2):
    png_write(os.path.join(f, "q%d.png" % k), [r.astype(">u2").tobytes() for r in rgba[k]], NX, 16, 6,
              png_chunk(b"oFFs", struct.pack(">iiB", 3, 5, 0)))
ok("png_rgba16_a", "u16", rgba[..., 3], "folder", [f], channel=3)

# TIFF codecs and layouts: LZW, PackBits, tiled u16, separate planes, MinIsWhite, palette, half
f = d("tiff_lzw")
vol = rand((3, NY, NX), np.uint16, 0, 65535)
for k in range(3):
    oiio_write(os.path.join(f, "l%d.tif" % k), vol[k], "uint16", "lzw")
ok("tiff_lzw", "u16", vol, "folder", [f])
f = d("tiff_packbits")
vol = rand((3, NY, NX), np.uint8, 0, 3)   # runs: PackBits compresses them
for k in range(3):
    oiio_write(os.path.join(f, "b%d.tif" % k), vol[k], "uint8", "packbits")
ok("tiff_packbits", "u8", vol, "folder", [f])
f = d("tiff_tiled")
vol = rand((3, 40, 37), np.int16, -32768, 32767)
for k in range(3):
    tifffile.imwrite(os.path.join(f, "t%d.tif" % k), vol[k], photometric="minisblack", tile=(16, 16),
                     compression="zlib")
ok("tiff_tiled_i16", "i16", vol, "folder", [f])
f = d("tiff_planar")
rgb16 = rand((3, 3, NY, NX), np.uint16, 0, 65535)       # [slice, channel, row, column]
for k in range(3):
    tifffile.imwrite(os.path.join(f, "s%d.tif" % k), rgb16[k], photometric="rgb", planarconfig="separate")
ok("tiff_planar_g", "u16", rgb16[:, 1], "folder", [f], channel=1)
f = d("tiff_miniswhite")
vol = rand((3, NY, NX), np.uint8, 0, 255)
for k in range(3):
    tifffile.imwrite(os.path.join(f, "w%d.tif" % k), vol[k], photometric="miniswhite")
ok("tiff_miniswhite", "u8", 255 - vol, "folder", [f])        # inverted to MinIsBlack
f = d("tiff_miniswhite16")
vol = rand((3, NY, NX), np.uint16, 0, 65535)
for k in range(3):
    tifffile.imwrite(os.path.join(f, "w%d.tif" % k), vol[k], photometric="miniswhite")
ok("tiff_miniswhite16", "u16", vol, "folder", [f])           # OpenImageIO inverts 8 bits only
f = d("tiff_palette")
cmap = rand((3, 256), np.uint16, 0, 65535)
idx = rand((3, NY, NX), np.uint8, 0, 255)
for k in range(3):
    tifffile.imwrite(os.path.join(f, "c%d.tif" % k), idx[k], photometric="palette", colormap=cmap)
ok("tiff_palette_b", "u8", (cmap[2][idx] // 257).astype(np.uint8), "folder", [f], channel=2)
f = d("tiff_half")
vol = RNG.normal(0, 100, size=(3, NY, NX)).astype(np.float16)
for k in range(3):
    tifffile.imwrite(os.path.join(f, "h%d.tif" % k), vol[k], photometric="minisblack")
ok("tiff_half", "f32", vol.astype(np.float32), "folder", [f])
for tname, dt in (("i8", np.int8), ("i32", np.int32), ("f64", np.float64)):
    f = d("tiff_" + tname)
    info = np.iinfo(dt) if np.issubdtype(dt, np.integer) else None
    vol = (rand((2, NY, NX), dt, info.min, info.max) if info else
           RNG.normal(0, 1e9, size=(2, NY, NX)).astype(dt))
    for k in range(2):
        tifffile.imwrite(os.path.join(f, "v%d.tif" % k), vol[k], photometric="minisblack",
                         byteorder=">" if tname == "f64" else "<")
    ok("tiff_" + tname, tname, vol, "folder", [f])
f = d("tiff_u32")
vol = rand((2, NY, NX), np.uint32, 0, 2**32 - 1)
for k in range(2):
    tifffile.imwrite(os.path.join(f, "v%d.tif" % k), vol[k], photometric="minisblack")
ok("tiff_u32", "f64", vol.astype(np.float64), "folder", [f])
# JPEG-compressed RGB (lossy): expected as OpenImageIO's own bindings decode it (both builds
# decode with libtiff and libjpeg, so they agree with each other and with this)
f = d("tiff_jpeg")
src = rand((2, 16, 24, 3), np.uint8, 0, 255)
src = np.repeat(np.repeat(src[:, ::4, ::4], 4, axis=1), 4, axis=2)     # blocks JPEG keeps well
jpeg_expected = []
for k in range(2):
    path = os.path.join(f, "j%d.tif" % k)
    oiio_write(path, src[k], "uint8", "jpeg")
    inp = oiio.ImageInput.open(path)
    jpeg_expected.append(inp.read_image(0, 0, 1, 2, "uint8")[:, :, 0])
    inp.close()
ok("tiff_jpeg_g", "u8", np.stack(jpeg_expected), "folder", [f], channel=1)

# JPEG slices: the OpenImageIO build reads them (expected as OpenImageIO's bindings decode
# them); the portable build lists them and refuses them by name
f = d("jpeg_folder")
jpeg_expected = []
for k in range(2):
    path = os.path.join(f, "j%d.jpg" % k)
    oiio_write(path, src[k][:, :, 0], "uint8", None)
    inp = oiio.ImageInput.open(path)
    jpeg_expected.append(inp.read_image(0, 0, 0, 1, "uint8")[:, :, 0])
    inp.close()
ok("jpeg_folder", "u8", np.stack(jpeg_expected), "folder", [f], only="oiio")
err("jpeg_folder", UNSUPPORTED, "j0.jpg: JPEG images are not read by this build", [f], only="portable")

# OpenEXR: channels in OpenImageIO's order (R, G, B, A, then the rest), uint channels
f = d("exr_channels")
chans = RNG.normal(0, 10, size=(2, NY, NX, 5)).astype(np.float32)   # written as Z, B, G, R, A
for k in range(2):
    spec = oiio.ImageSpec(NX, NY, 5, "float")
    spec.channelnames = ("Z", "B", "G", "R", "A")
    out = oiio.ImageOutput.create(os.path.join(f, "c%d.exr" % k))
    assert out.open(os.path.join(f, "c%d.exr" % k), spec), out.geterror()
    assert out.write_image(np.ascontiguousarray(chans[k])), out.geterror()
    out.close()
ok("exr_channel_z", "f32", chans[..., 0], "folder", [f], channel=4)  # R G B A Z: Z is channel 4
ok("exr_channel_r", "f32", chans[..., 3], "folder", [f], channel=0)
f = d("exr_uint")
vol = rand((2, NY, NX), np.uint32, 0, 2**32 - 1)
for k in range(2):
    oiio_write(os.path.join(f, "u%d.exr" % k), vol[k], "uint", "zip", channels=["Y"])
ok("exr_uint", "f64", vol.astype(np.float64), "folder", [f])
f = d("exr_tiled")
vol = RNG.normal(0, 10, size=(2, 40, 37)).astype(np.float16)
for k in range(2):
    oiio_write(os.path.join(f, "t%d.exr" % k), vol[k], "half", "zip", channels=["Y"],
               extra={"tile_width": 16, "tile_height": 16})
ok("exr_tiled", "f32", vol.astype(np.float32), "folder", [f])

# ---- bad stacks ------------------------------------------------------------------------------

def gray_folder(name, n=3, dt=np.uint8, fmt="uint8", compression="none", ext="tif"):
    f = d(name)
    vol = rand((n, NY, NX), dt, 0, 200)
    paths = []
    for k in range(n):
        paths.append(os.path.join(f, "b_%02d.%s" % (k, ext)))
        oiio_write(paths[-1], vol[k], fmt, compression)
    return f, paths

f, paths = gray_folder("missing_in_list")
err("missing_in_list", NOT_FOUND, "nothere.tif", [paths[0], os.path.join(f, "nothere.tif"), paths[1]])
err("missing_folder", NOT_FOUND, "no_such_folder", [os.path.join(OUT, "no_such_folder")])

f, paths = gray_folder("unknown_file")
open(os.path.join(f, "b_01.tif"), "w").write("this is not a TIFF file at all\n")
err("unknown_file", UNREADABLE, "b_01.tif", [f])

# truncated TIFF (uncompressed): the last slice loses half its pixel data
f, paths = gray_folder("truncated", n=3, dt=np.uint16, fmt="uint16")
# tifffile writes the IFD before the pixel data: cutting the file's end cuts pixels
tifffile.imwrite(paths[2], rand((NY, NX), np.uint16, 0, 200), photometric="minisblack")
sz = os.path.getsize(paths[2])
os.truncate(paths[2], sz - (NX * NY))  # half of the last rows' bytes
err("truncated", CORRUPT, "b_02.tif", [f])

# deflate TIFF with a corrupted strip: garbage in the middle of the compressed data
f = d("deflate_corrupt")
big = rand((3, 64, 64), np.uint16, 0, 65535)
paths = []
for k in range(3):
    paths.append(os.path.join(f, "z_%d.tif" % k))
    tifffile.imwrite(paths[-1], big[k], photometric="minisblack", compression="zlib",
                     rowsperstrip=64)
with tifffile.TiffFile(paths[1]) as t:
    off = t.pages[0].dataoffsets[0]
    cnt = t.pages[0].databytecounts[0]
with open(paths[1], "r+b") as fh:
    fh.seek(off + cnt // 2)
    fh.write(bytes(RNG.integers(0, 255, size=64, endpoint=True).astype(np.uint8)))
err("deflate_corrupt", CORRUPT, "z_1.tif", [f])

# the same in a tiled deflate TIFF (OIIO's tile path)
f = d("tiled_corrupt")
paths = []
for k in range(3):
    paths.append(os.path.join(f, "t_%d.tif" % k))
    tifffile.imwrite(paths[-1], big[k], photometric="minisblack", compression="zlib", tile=(16, 16))
with tifffile.TiffFile(paths[2]) as t:
    off = t.pages[0].dataoffsets[5]
    cnt = t.pages[0].databytecounts[5]
with open(paths[2], "r+b") as fh:
    fh.seek(off + cnt // 2)
    fh.write(bytes(RNG.integers(0, 255, size=64, endpoint=True).astype(np.uint8)))
err("tiled_corrupt", CORRUPT, "t_2.tif", [f])

# a truncated EXR (uncompressed: one line per chunk), the second slice loses its end
f = d("exr_truncated")
paths = []
for k in range(3):
    paths.append(os.path.join(f, "e_%d.exr" % k))
    oiio_write(paths[-1], RNG.normal(0, 1, size=(64, 64)).astype(np.float32), "float", "none",
               channels=["Y"])
os.truncate(paths[1], os.path.getsize(paths[1]) // 2)
err("exr_truncated", CORRUPT, "e_1.exr", [f])

f, paths = gray_folder("size_mismatch")
oiio_write(paths[1], rand((NY - 1, NX), np.uint8, 0, 9), "uint8")
err("size_mismatch", MISMATCH, "b_01.tif", [f])

f, paths = gray_folder("many_mismatch", n=150)
oiio_write(paths[141], rand((NY, NX + 1), np.uint8, 0, 9), "uint8")
err("many_mismatch", MISMATCH, "b_141.tif: size 14x9", [f])

f, paths = gray_folder("type_mismatch")
oiio_write(paths[2], rand((NY, NX), np.uint16, 0, 9), "uint16")
err("type_mismatch", MISMATCH, "b_02.tif", [f])

f, paths = gray_folder("channel_mismatch")
oiio_write(paths[1], rand((NY, NX, 3), np.uint8, 0, 9), "uint8")
err("channel_mismatch", MISMATCH, "b_01.tif", [f])

# an EXR whose data window is offset: same width and height, different window
f, paths = gray_folder("window_mismatch", dt=np.float32, fmt="float", compression="zip", ext="exr")
s = oiio.ImageSpec(NX, NY, 1, "float")
s.x, s.y = 3, 2
out = oiio.ImageOutput.create(paths[1])
out.open(paths[1], s)
out.write_image(np.zeros((NY, NX, 1), np.float32))
out.close()
err("window_mismatch", MISMATCH, "b_01.exr", [f])

# a 3D image (OpenVDB grids are read by OIIO with depth > 1) is not a slice
import pyopenvdb
f = d("volume3d")
for k in range(2):
    g = pyopenvdb.FloatGrid()
    g.copyFromArray(np.ones((4, 5, 6), np.float32))
    g.name = "density"
    pyopenvdb.write(os.path.join(f, "v%d.vdb" % k), grids=[g])
err("volume3d", UNSUPPORTED, "v0.vdb", [f])

d("empty_folder")
err("empty_folder", NOT_FOUND, "empty_folder", [os.path.join(OUT, "empty_folder")])
f, paths = gray_folder("one_slice", n=1)
err("one_slice_folder", TOO_FEW, "b_00.tif", [f])
err("one_slice_file", TOO_FEW, "b_00.tif", [paths[0]])
err("glob_no_match", NOT_FOUND, "nomatch_*.tif", [os.path.join(OUT, "u8_folder", "nomatch_*.tif")])
err("pattern_missing", NOT_FOUND, "slice_0013.tif", [os.path.join(OUT, "u16_pattern", "slice_%04d.tif")],
    first=10, count=5)
# an ImageJ hyperstack with 2 channels: its pages alternate channels, not slices
f = d("hyperstack")
tifffile.imwrite(os.path.join(f, "hs.tif"), rand((3, 2, NY, NX), np.uint8, 0, 255), imagej=True,
                 metadata={"axes": "ZCYX"})
err("hyperstack", UNSUPPORTED, "2 channels", [os.path.join(f, "hs.tif")])
# 1-bit TIFFs as tifffile (and Pillow) write them, without a BitsPerSample tag: OIIO 2.4 misreads
f = d("bilevel")
for k in range(2):
    m = np.zeros((NY, NX), bool)
    m[2:5, 3:9 + k] = True
    tifffile.imwrite(os.path.join(f, "mask_%d.tif" % k), m)
err("bilevel", UNSUPPORTED, "mask_0.tif: a 1-bit", [f], only="oiio")
# libtiff reads them right (BitsPerSample's default is 1); tifffile marks them MinIsWhite, so
# the delivered samples are inverted, as for every MinIsWhite image (1 - the stored bit)
ok("bilevel", "u8", 1 - np.stack([tifffile.imread(os.path.join(f, "mask_%d.tif" % k))
                                  for k in range(2)]).astype(np.uint8),
   "folder", [f], only="portable")
err("multipage_in_list", UNSUPPORTED, "stack.tif: has 5 pages",
    [os.path.join(OUT, "multipage", "stack.tif"), os.path.join(OUT, "u16_pattern", "slice_0000.tif")])
err("rgb_no_channel", UNSUPPORTED, "--channel", [os.path.join(OUT, "rgb")])
err("rgb_bad_channel", UNSUPPORTED, "no channel 5", [os.path.join(OUT, "rgb")], channel=5)


def huge_tiff(path, w, h, pages):
    """A valid-looking TIFF header declaring huge pages whose data is absent."""
    entries_per_ifd = 8
    ifd_size = 2 + entries_per_ifd * 12 + 4
    buf = bytearray(b"II*\x00" + struct.pack("<I", 8))
    for p in range(pages):
        start = 8 + p * ifd_size
        nxt = start + ifd_size if p + 1 < pages else 0
        ent = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 4096), (278, 4, 1, h), (279, 4, 1, w * h)]
        buf += struct.pack("<H", len(ent))
        for tag, typ, n, val in ent:
            buf += struct.pack("<HHII", tag, typ, n, val)
        buf += struct.pack("<I", nxt)
        assert len(buf) == start + ifd_size
    buf += bytes(4096 - len(buf)) + bytes(4096)
    open(path, "wb").write(buf)


f = d("too_large")
huge_tiff(os.path.join(f, "huge.tif"), 60000, 60000, 40)   # 40 x 3.35 GiB = 134 GiB of u8
err("too_large", TOO_LARGE, "GiB", [os.path.join(f, "huge.tif")])

for backend, manifest in (("oiio", "manifest.tsv"), ("portable", "manifest_portable.tsv")):
    with open(os.path.join(OUT, manifest), "w") as fh:
        fh.write("\n".join(line for only, line in LINES if only in (None, backend)) + "\n")
print("gen_stacks: %d cases in %s" % (len(LINES), OUT))
