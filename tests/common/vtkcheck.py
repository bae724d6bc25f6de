"""Independent checks of a mesh with VTK (Debian's python3-vtk9), shared by
tests/cli/test_postprocess.py, tests/io/test_dicom_positions.py and
bench/postprocess_bench.py: VTK reads the file itself and judges it with its
own filters, nothing of isomend's."""
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def read_poly(path):
    """A PLY read by vtkPLYReader, not cleaned (cleaning merges points)."""
    r = vtk.vtkPLYReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def feature_edges(poly):
    """(boundary, non-manifold) edge counts by vtkFeatureEdges."""
    out = []
    for boundary in (True, False):
        fe = vtk.vtkFeatureEdges()
        fe.SetInputData(poly)
        fe.SetBoundaryEdges(boundary)
        fe.SetNonManifoldEdges(not boundary)
        fe.SetFeatureEdges(False)
        fe.SetManifoldEdges(False)
        fe.Update()
        out.append(fe.GetOutput().GetNumberOfLines())
    return tuple(out)


def components(poly):
    """Connected regions by vtkPolyDataConnectivityFilter."""
    cf = vtk.vtkPolyDataConnectivityFilter()
    cf.SetInputData(poly)
    cf.SetExtractionModeToAllRegions()
    cf.Update()
    return cf.GetNumberOfExtractedRegions()


def distances(src_poly, dst_poly):
    """Distance from every vertex of src_poly to the surface dst_poly
    (vtkCellLocator.FindClosestPoint)."""
    loc = vtk.vtkCellLocator()
    loc.SetDataSet(dst_poly)
    loc.BuildLocator()
    pts = vtk_to_numpy(src_poly.GetPoints().GetData()).astype(np.float64)
    p = [0.0, 0.0, 0.0]
    cid, sid, d2 = vtk.reference(0), vtk.reference(0), vtk.reference(0.0)
    out = np.empty(len(pts))
    for i, q in enumerate(pts):
        loc.FindClosestPoint(q.tolist(), p, cid, sid, d2)
        out[i] = d2.get()
    return np.sqrt(out)
