"""The workbench's file filter for body imports; the readers are :mod:`geometry.importers`
(:func:`geometry.importers.read_outline`: CSV or DXF profiles and outlines, 2D meshes)."""

from __future__ import annotations

#: File filter of the import dialog.
IMPORT_FILTER = ("Slope profile or outline (*.csv *.dxf *.msh *.vtk *.vtu *.xdmf);;CSV points (*.csv);;"
                 "DXF drawing (*.dxf);;Mesh (*.msh *.vtk *.vtu *.xdmf);;All files (*)")
