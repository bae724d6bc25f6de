"""Label maps the host tests share (MeshLab, Blender, the Python module):
three touching structures and a 3D Slicer-style .seg.nrrd that names and
colours them, so that each host is checked on the same segmentation."""
import numpy as np

# value, Segment*_Name, Segment*_Color (sRGB fractions, as 3D Slicer writes them)
SEGMENTS = [(1, "Liver", (1, 0, 0)), (2, "Left kidney", (0, 0.5, 1)), (3, "Tumour", (1, 1, 0))]


def organs(n=24):
    """array[z, y, x] uint8: two boxes side by side (1, 2) and a ball (3)
    resting on them; background 0."""
    z, y, x = np.mgrid[0:n, 0:n, 0:n]
    v = np.zeros((n, n, n), np.uint8)
    v[3:13, 4:18, 3:11] = 1
    v[3:13, 4:18, 11:20] = 2
    v[((x - 11.3) ** 2 + (y - 10.6) ** 2 + (z - 15.2) ** 2 < 4.4 ** 2) & (v == 0)] = 3
    return v


def write_seg_nrrd(path, vol, spacings, segments=SEGMENTS):
    """A .seg.nrrd (uint8 labels, raw) whose header's Segment*_ keys name
    and colour `segments`."""
    keys = "".join("Segment%d_Name:=%s\nSegment%d_Color:=%s\nSegment%d_LabelValue:=%d\n"
                   % (i, name, i, " ".join("%g" % c for c in color), i, value)
                   for i, (value, name, color) in enumerate(segments))
    header = ("NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nspacings: %g %g %g\n"
              "encoding: raw\n%s\n" % (vol.shape[2], vol.shape[1], vol.shape[0], *spacings, keys))
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.ascontiguousarray(vol, np.uint8).tobytes())
