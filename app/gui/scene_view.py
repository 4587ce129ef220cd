"""The 2D model view: background grid, domain box with its boundary conditions, bodies coloured
by material, rigid structures (grey, hatched, labelled with their contact), targets (vertical
lines or markers with their names), the loads of the chosen stage (surcharges as arrows onto the
ground, seismic coefficients as a labelled arrow), a preview of the seeded particles, and drawing
and editing of body and structure polygons.

Mouse, in the *select* mode: click a body or structure to select it, drag one of its vertices
(snapped to the grid when snapping is on), click and drag a target to move it, drag empty space
to pan, wheel or right-drag to zoom. In the *draw* mode every click adds a vertex; clicking the
first vertex again, double-clicking or Enter closes the polygon into a new body (or structure,
see :meth:`SceneView.set_mode`); Backspace removes the last vertex and Escape cancels. Delete
removes the selected vertex. Problems of a shape (crossing edges, vertices outside the domain)
are drawn in red where they are.

Everything here runs on the GUI thread; the only VTK objects are those of the embedded
:class:`pyvistaqt.QtInteractor`, released by :meth:`SceneView.close_view`.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
from PySide6.QtCore import QEvent, QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QKeyEvent, QMouseEvent
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from app.gui.document import (
    MAX_SEEDED_PARTICLES,
    POLYGON_KINDS,
    WATER_LINE_KEYS,
    ProjectDocument,
    format_number,
    get_path,
    water_line_path,
)
from app.gui.object_panels import STRUCTURE_COLOR, TARGET_COLOR, contact_text
from app.gui.panels import material_color

logger = logging.getLogger(__name__)

PICK_PIXELS = 9.0
MAX_GRID_LINES = 100
BOUNDARY_STYLE = {
    "fixed": ("#202124", 5),
    "slip": ("#1a73e8", 4),
    "friction": ("#e37400", 4),
    "open": ("#9aa0a6", 1),
    "periodic": ("#188038", 3),
}
PROBLEM_COLOR = "#d93025"
#: surcharges and seismic forces in the model view
LOAD_COLOR = "#9334e6"


def _as_points(polygon: Any) -> np.ndarray | None:
    """A polygon as an (K, 2) float array, or None when it is not one."""
    try:
        arr = np.asarray(polygon, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
        return None
    return arr


def _lines(segments: list[tuple[np.ndarray, np.ndarray]]) -> Any:
    import pyvista as pv

    points = np.zeros((2 * len(segments), 3))
    for i, (a, b) in enumerate(segments):
        points[2 * i, :2] = a
        points[2 * i + 1, :2] = b
    cells = np.column_stack([np.full(len(segments), 2), np.arange(0, 2 * len(segments), 2),
                             np.arange(1, 2 * len(segments), 2)]).ravel()
    return pv.PolyData(points, lines=cells)


def _points3(xy: np.ndarray, z: float = 0.0) -> np.ndarray:
    out = np.zeros((len(xy), 3))
    out[:, :2] = xy
    out[:, 2] = z
    return out


def _hatch(poly: np.ndarray, step_m: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Diagonal (45°) hatching lines of a simple polygon, ``step_m`` apart (shapely clips them)."""
    from shapely.geometry import LineString, Polygon

    shape = Polygon(poly)
    if not shape.is_valid or shape.area <= 0 or step_m <= 0:
        return []
    x0, y0, x1, y1 = shape.bounds
    span = (x1 - x0) + (y1 - y0)
    out = []
    for c in np.arange(x0 - (y1 - y0), x1 + step_m, step_m):  # lines x - y = c - y0 ... as x = c + (y - y0)
        piece = shape.intersection(LineString([(c, y0), (c + span, y0 + span)]))
        parts = getattr(piece, "geoms", [piece])
        for part in parts:
            coords = np.asarray(getattr(part, "coords", []), dtype=float)
            if len(coords) >= 2:
                out.append((coords[0], coords[-1]))
    return out


def target_place(target: Any) -> tuple[float, float | None] | None:
    """(x, y) of a point target, (x, None) of a line target, None when it has no valid place."""
    point = target.get("point_m") if isinstance(target, dict) else None
    if point is not None:
        pts = _as_points([point])
        return None if pts is None else (float(pts[0, 0]), float(pts[0, 1]))
    x = target.get("x_m") if isinstance(target, dict) else None
    if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x):
        return float(x), None
    return None


def water_line_noun(slot: int) -> str:
    """``"phreatic line"``, ``"free-water line"``, ``"phreatic line of stage 2"``, ..."""
    stage, which = divmod(int(slot), 2)
    noun = ("phreatic line", "free-water line")[which]
    return noun if stage == 0 else f"{noun} of stage {stage}"


def set_water_line(doc: ProjectDocument, slot: int, line: list[list[float]] | None, text: str) -> bool:
    """Set (None: remove) water line ``slot`` as one undo step. Removing the project's phreatic line
    removes the water: ``[water]`` and every stage's water move; a stage's water table left with
    no line goes too."""
    stage, which = divmod(int(slot), 2)
    key = WATER_LINE_KEYS[which]

    def mutate(d: dict[str, Any]) -> None:
        if stage == 0:
            table = d
            name = "water"
        else:
            table = d["stages"][stage - 1]
            name = "water"
        if line is not None:
            if not isinstance(table.get(name), dict):
                table[name] = {}
            table[name][key] = [[float(p[0]), float(p[1])] for p in line]
            return
        if slot == 0:
            d.pop("water", None)
            for st in d.get("stages", []):
                if isinstance(st, dict):
                    st.pop("water", None)
            return
        if isinstance(table.get(name), dict):
            table[name].pop(key, None)
            if stage > 0 and not table[name]:
                table.pop(name)

    return doc.edit(text, mutate)


def _left(event: QEvent) -> bool:
    return event.button() == Qt.MouseButton.LeftButton  # type: ignore[attr-defined]


def _rgb(color: str) -> tuple[float, float, float]:
    color = color.lstrip("#")
    return tuple(int(color[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


class SceneView(QWidget):
    """The model view of a :class:`ProjectDocument`.

    Signals
    -------
    cursorMoved(float, float)
        Mouse position in metres (for the status bar).
    modeChanged(str)
        "select" or "draw".
    message(str)
        A short hint for the status bar.
    """

    cursorMoved = Signal(float, float)
    modeChanged = Signal(str)
    message = Signal(str)

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from pyvistaqt import QtInteractor

        self.doc = doc
        self.plotter = QtInteractor(self, auto_update=False)
        self.legend = QLabel("")
        self.legend.setStyleSheet("padding: 3px 6px; background: white; color: #3c4043;")
        self.legend.setTextFormat(Qt.TextFormat.RichText)
        self.legend.setWordWrap(True)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addWidget(self.legend)
        layout.addWidget(self.plotter, 1)
        self.plotter.set_background("white")
        self.plotter.enable_parallel_projection()
        self.plotter.enable_custom_trackball_style(
            left="pan", shift_left="pan", control_left="pan", middle="pan", shift_middle="pan",
            control_middle="pan", right="dolly", shift_right="dolly", control_right="dolly",
        )
        self.plotter.installEventFilter(self)
        self.mode = "select"
        self.snap = True
        self.show_particles = True
        self._preview_refused = False  # the status bar says the particle preview was refused
        self.draft: list[list[float]] = []
        #: what a drawn polygon becomes: "bodies" or "structures"; or "water": a water line
        self.draw_kind = "bodies"
        #: the water line being drawn (a slot of app.gui.document.water_line_path)
        self.draw_slot = 0
        #: the stage whose loads are drawn (None: none), and the names of those drawn
        self.loads_stage: int | None = None
        self.drawn_loads: list[str] = []
        self._cursor: np.ndarray | None = None
        self._drag: tuple[str, int, int | None] | None = None
        self._drag_count = 0
        self._fitted_domain: Any = None
        self._auto_fit = True
        self.grid_step = 1
        self.preview_count = 0
        self._closed = False
        self._preview_timer = QTimer(self)
        self._preview_timer.setSingleShot(True)
        self._preview_timer.setInterval(120)
        self._preview_timer.timeout.connect(self._draw_particles)
        doc.changed.connect(self._on_changed)
        doc.selection.changed.connect(self._on_selection)
        self.redraw()

    # -- lifetime -----------------------------------------------------------------------------

    def close_view(self) -> None:
        """Release the VTK window and interactor (before the widget goes away)."""
        if self._closed:
            return
        self._closed = True
        self._preview_timer.stop()
        self.plotter.removeEventFilter(self)
        try:
            self.doc.changed.disconnect(self._on_changed)
            self.doc.selection.changed.disconnect(self._on_selection)
        except (RuntimeError, TypeError):  # already disconnected with the document
            pass
        self.plotter.close()  # releases the render window; the widget goes with its window

    # -- coordinates ----------------------------------------------------------------------------

    def _scale(self) -> float:
        return float(self.plotter.devicePixelRatioF())

    def widget_to_world(self, pos: QPointF) -> np.ndarray:
        """Metres under a widget position (logical pixels)."""
        s = self._scale()
        x = pos.x() * s
        y = (self.plotter.height() - pos.y() - 1) * s
        r = self.plotter.renderer
        r.SetDisplayPoint(x, y, 0.0)
        r.DisplayToWorld()
        wx, wy, _wz, w = r.GetWorldPoint()
        if w == 0:
            w = 1.0
        return np.array([wx / w, wy / w])

    def world_to_widget(self, xy: Any) -> QPointF:
        """Widget position (logical pixels) of a point in metres."""
        r = self.plotter.renderer
        r.SetWorldPoint(float(xy[0]), float(xy[1]), 0.0, 1.0)
        r.WorldToDisplay()
        dx, dy, _ = r.GetDisplayPoint()
        s = self._scale()
        return QPointF(dx / s, self.plotter.height() - 1 - dy / s)

    def pixel_size_m(self) -> float:
        """Metres per logical pixel at the current zoom."""
        scale = self.plotter.camera.parallel_scale
        return 2.0 * scale / max(1, self.plotter.height())

    # -- camera -------------------------------------------------------------------------------

    def _domain_box(self) -> tuple[float, float, float, float] | None:
        origin = _as_points([self.doc.get("domain.origin_m", [0.0, 0.0])])
        size = _as_points([self.doc.get("domain.size_m")])
        if origin is None or size is None or np.any(size <= 0):
            return None
        x0, y0 = origin[0]
        w, h = size[0]
        return float(x0), float(x0 + w), float(y0), float(y0 + h)

    def fit(self) -> None:
        """Show the whole domain with a margin for the boundary labels."""
        box = self._domain_box() or (0.0, 1.0, 0.0, 1.0)
        x0, x1, y0, y1 = box
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        w, h = (x1 - x0) * 1.12, (y1 - y0) * 1.25
        aspect = max(1, self.plotter.width()) / max(1, self.plotter.height())
        cam = self.plotter.camera
        cam.focal_point = (cx, cy, 0.0)
        cam.position = (cx, cy, 10.0 * max(w, h))
        cam.up = (0.0, 1.0, 0.0)
        cam.parallel_scale = max(h / 2.0, w / 2.0 / aspect)
        self.plotter.renderer.ResetCameraClippingRange()
        self._fitted_domain = box
        self._auto_fit = True
        self.plotter.render()

    def resizeEvent(self, event: Any) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        # follow the window's size until the user pans or zooms; then keep their view
        if not self._closed and self._fitted_domain is not None and self._auto_fit:
            self.fit()

    # -- drawing the scene ----------------------------------------------------------------------

    def _add(self, mesh: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("render", False)
        kwargs.setdefault("reset_camera", False)
        return self.plotter.add_mesh(mesh, **kwargs)

    def _on_changed(self, sections: frozenset) -> None:
        self.redraw(sections)

    def _on_selection(self) -> None:
        if not self._closed:
            self._draw_bodies()
            self.plotter.render()

    def redraw(self, sections: frozenset | None = None) -> None:
        """Draw what changed (everything when ``sections`` is None)."""
        if self._closed:
            return
        every = sections is None
        if every or "domain" in sections:
            self._draw_domain()
        if every or sections & {"domain", "bodies", "materials", "structures", "targets", "water", "stages"}:
            self._draw_bodies()
        if every or sections & {"domain", "bodies", "particles", "materials", "structures"}:
            self._preview_timer.start()
        box = self._domain_box()
        if box is not None and box != self._fitted_domain:
            self.fit()
        else:
            self.plotter.render()

    def _draw_domain(self) -> None:
        pl = self.plotter
        for name in ("grid", "labels", "side-left", "side-right", "side-bottom", "side-top"):
            pl.remove_actor(name, render=False)
        box = self._domain_box()
        cell = self.doc.get("domain.cell_size_m")
        if box is None:
            return
        x0, x1, y0, y1 = box
        if isinstance(cell, (int, float)) and cell > 0:
            nx, ny = max(1, round((x1 - x0) / cell)), max(1, round((y1 - y0) / cell))
            step = max(1, math.ceil(max(nx, ny) / MAX_GRID_LINES))
            self.grid_step = step
            segs = [(np.array([x0 + i * cell, y0]), np.array([x0 + i * cell, y1])) for i in range(0, nx + 1, step)]
            segs += [(np.array([x0, y0 + j * cell]), np.array([x1, y0 + j * cell])) for j in range(0, ny + 1, step)]
            self._add(_lines(segs), color="#e3e6ea", line_width=1, name="grid", pickable=False,
                        render=False, lighting=False)
        corners = {
            "bottom": (np.array([x0, y0]), np.array([x1, y0])),
            "right": (np.array([x1, y0]), np.array([x1, y1])),
            "top": (np.array([x1, y1]), np.array([x0, y1])),
            "left": (np.array([x0, y1]), np.array([x0, y0])),
        }
        labels, points = [], []
        pad = 0.035 * max(x1 - x0, y1 - y0)
        offsets = {"bottom": (0, -pad), "top": (0, pad * 0.6), "left": (-pad, 0), "right": (pad, 0)}
        for side, (a, b) in corners.items():
            boundary = self.doc.get(f"domain.boundaries.{side}", "slip")
            kind = boundary.get("type", "?") if isinstance(boundary, dict) else str(boundary)
            color, width = BOUNDARY_STYLE.get(kind, ("#9aa0a6", 1))
            self._add(_lines([(a, b)]), color=color, line_width=width, name=f"side-{side}",
                        pickable=False, render=False, lighting=False)
            text = kind
            if kind == "friction" and isinstance(boundary, dict):
                text = f"friction {format_number(boundary.get('friction_angle_deg', '?'))}°"  # as the structures'
            mid = (a + b) / 2 + np.array(offsets[side])
            labels.append(text)
            points.append([mid[0], mid[1], 0.01])
        pl.add_point_labels(np.array(points), labels, name="labels", font_size=11, text_color="#3c4043",
                            shape=None, show_points=False, always_visible=True, render=False,
                            justification_horizontal="center", reset_camera=False)

    def _material_index(self, name: Any) -> int:
        names = self.doc.material_names
        return names.index(name) if name in names else -1

    def _polygons(self, kind: str) -> list[dict[str, Any]]:
        items = self.doc.get(kind, [])
        return [it for it in items if isinstance(it, dict)] if isinstance(items, list) else []

    def _draw_bodies(self) -> None:
        """Bodies (filled by material), structures (grey, hatched), shape problems and the selection."""
        import pyvista as pv

        from geometry.polygons import self_intersections

        pl = self.plotter
        for name in ("fills", "outlines", "bad-edges", "bad-points", "vertices", "vertex", "draft",
                     "draft-points", "legend", "structure-fills", "structure-hatch", "structure-outlines",
                     "structure-labels-labels"):  # add_point_labels names its actor NAME-labels
            pl.remove_actor(name, render=False)
        fills: dict[str, list[Any]] = {kind: [] for kind in POLYGON_KINDS}
        outlines: dict[str, list[Any]] = {kind: [] for kind in POLYGON_KINDS}
        bad_segments, bad_points, hatch, labels, label_points = [], [], [], [], []
        box = self._domain_box()
        for kind in POLYGON_KINDS:
            for i, item in enumerate(self._polygons(kind)):
                poly = _as_points(item.get("polygon_m"))
                if poly is None or len(poly) < 2:
                    continue
                if kind == "bodies":
                    color = _rgb(material_color(self._material_index(item.get("material"))))
                else:
                    color = _rgb(STRUCTURE_COLOR)
                if len(poly) >= 3:
                    try:
                        crossings = self_intersections(poly)
                    except ValueError:
                        crossings = []
                    for a, b in crossings:
                        for e in (a, b):
                            bad_segments.append((poly[e], poly[(e + 1) % len(poly)]))
                    z = -0.01 if kind == "bodies" else -0.005
                    face = pv.PolyData(_points3(poly, z), faces=np.r_[len(poly), np.arange(len(poly))])
                    if not crossings:
                        try:
                            face = face.triangulate()
                        except (RuntimeError, ValueError):
                            logger.debug("could not triangulate %s %d", kind, i)
                        if kind == "structures":
                            hatch.extend(_hatch(poly, self._hatch_step(poly)))
                    face.cell_data["rgb"] = np.tile(np.array(color) * 255, (face.n_cells, 1)).astype(np.uint8)
                    fills[kind].append(face)
                ring = np.vstack([poly, poly[:1]])
                outlines[kind].extend((ring[k], ring[k + 1]) for k in range(len(poly)))
                if kind == "structures":
                    top = poly[np.argmax(poly[:, 1])]
                    labels.append(f"{item.get('name', '?')} ({contact_text(item.get('contact'))})")
                    lift = 0.02 * (box[3] - box[2]) if box is not None else 0.0
                    label_points.append([float(np.mean(poly[:, 0])), float(top[1]) + lift, 0.05])
                if box is not None:
                    outside = (poly[:, 0] < box[0] - 1e-9) | (poly[:, 0] > box[1] + 1e-9) | \
                              (poly[:, 1] < box[2] - 1e-9) | (poly[:, 1] > box[3] + 1e-9)
                    bad_points.extend(poly[outside])
        for kind, prefix, opacity in (("structures", "structure-", 0.75), ("bodies", "", 0.3)):
            if fills[kind]:
                merged = fills[kind][0].merge(fills[kind][1:]) if len(fills[kind]) > 1 else fills[kind][0]
                self._add(merged, scalars="rgb", rgb=True, opacity=opacity, name=f"{prefix}fills",
                          show_scalar_bar=False, render=False, lighting=False)
            if outlines[kind]:
                self._add(_lines(outlines[kind]), color="#3c4043" if kind == "bodies" else "#5f6368",
                          line_width=1.5 if kind == "bodies" else 2.0, name=f"{prefix}outlines", render=False,
                          lighting=False)
        if hatch:
            self._add(_lines(hatch), color="#5f6368", line_width=1, name="structure-hatch", render=False,
                      lighting=False, pickable=False)
        if labels:
            pl.add_point_labels(np.array(label_points), labels, name="structure-labels", font_size=10,
                                text_color="#3c4043", shape=None, show_points=False, always_visible=True,
                                render=False, reset_camera=False, justification_horizontal="center",
                                justification_vertical="bottom")
        if bad_segments:
            self._add(_lines(bad_segments), color=PROBLEM_COLOR, line_width=4, name="bad-edges", render=False,
                        lighting=False)
        if bad_points:
            self._add(pv.PolyData(_points3(np.array(bad_points), 0.02)), color=PROBLEM_COLOR, point_size=14,
                        render_points_as_spheres=True, name="bad-points", render=False)
        sel = self.doc.selection
        items = self._polygons(sel.kind) if sel.kind in POLYGON_KINDS else []
        if sel.index is not None and sel.index < len(items):
            poly = _as_points(items[sel.index].get("polygon_m"))
            if poly is not None and len(poly):
                ring = np.vstack([poly, poly[:1]])
                seg = [(ring[k], ring[k + 1]) for k in range(len(poly))]
                self._add(_lines(seg), color="#202124", line_width=3, name="draft", render=False, lighting=False)
                self._add(pv.PolyData(_points3(poly, 0.03)), color="white", point_size=10,
                            render_points_as_spheres=True, name="vertices", render=False)
                v = sel.vertex
                if v is not None and v < len(poly):
                    self._add(pv.PolyData(_points3(poly[v:v + 1], 0.04)), color="#fbbc04", point_size=15,
                                render_points_as_spheres=True, name="vertex", render=False)
        self._draw_targets()
        self._draw_water()
        self._draw_loads()
        self._update_legend()
        self._draw_draft()

    # -- ground water ---------------------------------------------------------------------------

    def _water_line(self, slot: int) -> np.ndarray | None:
        """Water line ``slot`` as (K, 2) points, None where the project has none there."""
        line = _as_points(get_path(self.doc.data, water_line_path(slot)))
        return line if line is not None and len(line) else None

    def shown_water_slots(self) -> list[int]:
        """The water lines drawn (and editable) in the view: the project's, and those of the stage
        whose line is selected or being drawn."""
        slots = [0, 1]
        sel = self.doc.selection
        stage = None
        if self.mode == "draw" and self.draw_kind == "water" and self.draw_slot >= 2:
            stage = self.draw_slot // 2
        elif sel.kind == "water" and sel.index is not None and sel.index >= 2:
            stage = sel.index // 2
        if stage is not None:
            slots += [2 * stage, 2 * stage + 1]
        return [k for k in slots if self._water_line(k) is not None]

    def _draw_water(self) -> None:
        """The project's phreatic line (blue), its free-water line (lighter) and the free water
        (shaded between that line, or the phreatic line, and the ground surface where it is above
        the ground); a selected stage's lines in a lighter blue; the selected line's vertices."""
        import pyvista as pv

        from app.render import (
            FREE_WATER_COLOR,
            FREE_WATER_LINE_COLOR,
            WATER_LINE_COLOR,
            free_water_polygons,
            water_line_across,
        )
        from solver.water import line_height

        pl = self.plotter
        for name in ("water-fill", "water-line-0", "water-line-1", "water-stage-0", "water-stage-1",
                     "water-line-0-halo", "water-line-1-halo", "water-stage-0-halo", "water-stage-1-halo",
                     "water-vertices", "water-vertex", "water-labels-labels"):
            pl.remove_actor(name, render=False)
        box = self._domain_box()
        if box is None:
            return
        x0, x1 = box[0], box[1]
        bodies = [p for p in (_as_points(b.get("polygon_m")) for b in self._polygons("bodies"))
                  if p is not None and len(p) >= 3]
        level = self._water_line(1)
        if level is None:
            level = self._water_line(0)
        if level is not None and len(level) >= 2 and np.all(np.diff(level[:, 0]) > 0):
            faces = []
            for ring in free_water_polygons(level, bodies, box):
                face = pv.PolyData(_points3(ring, -0.012), faces=np.r_[len(ring), np.arange(len(ring))])
                try:
                    face = face.triangulate()
                except (RuntimeError, ValueError):
                    logger.debug("could not triangulate the free water")
                faces.append(face)
            if faces:
                merged = faces[0].merge(faces[1:]) if len(faces) > 1 else faces[0]
                self._add(merged, color=FREE_WATER_COLOR, opacity=0.7, name="water-fill", lighting=False,
                          pickable=False)
        labels, label_points = [], []
        for slot in self.shown_water_slots():
            line = self._water_line(slot)
            stage, which = divmod(slot, 2)
            ordered = len(line) >= 2 and np.all(np.diff(line[:, 0]) > 0)
            across = water_line_across(line, x0, x1) if ordered else line
            name = f"water-line-{which}" if stage == 0 else f"water-stage-{which}"
            color = (WATER_LINE_COLOR if which == 0 else FREE_WATER_LINE_COLOR) if stage == 0 else "#64b5f6"
            width = (3.0 if which == 0 else 2.0) if stage == 0 else 2.5
            segments = [(across[k], across[k + 1]) for k in range(len(across) - 1)]
            if segments:
                # a white edge keeps the line readable over particles of any colour (tab10's blue)
                halo = self._add(_lines(segments), color="white", line_width=width + 3.0, name=f"{name}-halo",
                                 lighting=False, pickable=False)
                drawn = self._add(_lines(segments), color=color, line_width=width, name=name, lighting=False,
                                  pickable=False)
                halo.SetPosition(0.0, 0.0, 0.02)  # over the particles (z = 0.01), the line over its edge
                drawn.SetPosition(0.0, 0.0, 0.025)
                # named at a quarter (the project's) or three quarters (a stage's) of the domain
                at = x0 + (0.25 if stage == 0 else 0.75) * (x1 - x0) + (0.1 * (x1 - x0) if which else 0.0)
                kind = "free water" if which else "phreatic line"
                labels.append(kind if stage == 0 else f"{kind} after stage {stage}")
                lift = 0.015 * (box[3] - box[2])  # just above the line, clear of it
                label_points.append([at, float(line_height(line, np.array([at]))[0]) + lift, 0.05])
        if labels:
            self._add_water_labels(label_points, labels)
        sel = self.doc.selection
        if sel.kind == "water" and sel.index is not None:
            line = self._water_line(sel.index)
            if line is not None:
                self._add(pv.PolyData(_points3(line, 0.035)), color="white", point_size=10,
                          render_points_as_spheres=True, name="water-vertices")
                if sel.vertex is not None and sel.vertex < len(line):
                    self._add(pv.PolyData(_points3(line[sel.vertex:sel.vertex + 1], 0.045)), color="#fbbc04",
                              point_size=15, render_points_as_spheres=True, name="water-vertex")

    def _add_water_labels(self, points: list[list[float]], labels: list[str]) -> None:
        from app.render import WATER_LINE_COLOR

        self.plotter.add_point_labels(np.array(points), labels, name="water-labels", font_size=10,
                                      text_color=WATER_LINE_COLOR, shape="rect", shape_color="white",
                                      shape_opacity=0.85, margin=2, show_points=False,
                                      always_visible=True, render=False, reset_camera=False,
                                      justification_horizontal="center", justification_vertical="bottom")

    def move_water_vertex(self, slot: int, vertex: int, xy: Any, merge_key: str | None = None) -> None:
        """Move vertex ``vertex`` of water line ``slot`` to ``xy``; its x stays between its
        neighbours' (a water line has one height at each x)."""
        line = self._water_line(slot)
        if line is None or not 0 <= vertex < len(line):
            return
        x, y = float(xy[0]), float(xy[1])
        cell = self.doc.get("domain.cell_size_m")
        gap = 1e-3 * float(cell) if isinstance(cell, (int, float)) and cell > 0 else 1e-6
        if vertex > 0:
            x = max(x, float(line[vertex - 1, 0]) + gap)
        if vertex < len(line) - 1:
            x = min(x, float(line[vertex + 1, 0]) - gap)
        path = water_line_path(slot)

        def mutate(d: dict[str, Any]) -> None:
            get_path(d, path)[vertex] = [x, y]

        self.doc.edit(f"move vertex {vertex + 1} of the {water_line_noun(slot)}", mutate, merge_key)

    # -- loads ---------------------------------------------------------------------------------

    def set_loads_stage(self, index: int | None) -> None:
        """Draw the loads in force in stage ``index`` (None: none)."""
        if index != self.loads_stage:
            self.loads_stage = index
            if not self._closed:
                self._draw_loads()
                self._update_legend()
                self.plotter.render()

    def _draw_loads(self) -> None:
        """The surcharges in force in the chosen stage as arrows along gravity onto the ground,
        their lengths following the pressure (a line joins their tails), each named with its
        pressure; the stage's seismic coefficients as a label with the horizontal force's arrow."""
        from app.gui.loads_panel import loads_in_force, pressure_text, pressures
        from projects.loads import ground_height, out_of_slope

        pl = self.plotter
        for name in ("load-arrows", "load-tails", "load-labels-labels", "seismic-arrow", "seismic-labels-labels"):
            pl.remove_actor(name, render=False)
        self.drawn_loads = []
        box = self._domain_box()
        if box is None or self.loads_stage is None:
            return
        polygons = [p for p in (_as_points(b.get("polygon_m")) for b in self._polygons("bodies"))
                    if p is not None and len(p) >= 3]
        g = get_path(self.doc.data, "domain.gravity_m_s2", [0.0, -9.81])
        try:
            g = np.asarray(g, dtype=float)
            norm = float(np.linalg.norm(g))
            down = g / norm if norm > 0.0 and np.isfinite(norm) else np.array([0.0, -1.0])  # no gravity: down
        except (TypeError, ValueError):
            down = np.array([0.0, -1.0])
        if not np.all(np.isfinite(down)):
            down = np.array([0.0, -1.0])
        size = max(box[1] - box[0], box[3] - box[2])
        loads, _source = loads_in_force(self.doc.data, self.loads_stage)
        peak = max([abs(v) for load in loads for v in pressures(load) if v is not None] + [0.0])
        arrows, tails, labels, label_points = [], [], [], []
        for load in loads:
            a, b = load.get("from_m"), load.get("to_m")
            p0, p1 = pressures(load)
            if not all(isinstance(v, (int, float)) for v in (a, b)) or p0 is None or p1 is None or not b > a \
                    or not polygons:
                continue
            count = int(min(25, max(3, round((b - a) / (0.02 * size)) + 1)))
            xs = np.linspace(a, b, count)
            ys = ground_height(polygons, xs)
            ok = np.isfinite(ys)
            if not ok.any():
                continue
            length = 0.02 * size + 0.06 * size * (np.interp(xs, [a, b], [p0, p1]) / peak if peak > 0 else 0.0)
            heads, tops = np.c_[xs, ys], np.c_[xs, ys] - length[:, None] * down[None, :]
            side = np.array([-down[1], down[0]]) * 0.006 * size
            for head, top, good in zip(heads, tops, ok):
                if good:
                    arrows.append((top, head))
                    back = head - down * 0.012 * size
                    arrows.extend(((back + side, head), (back - side, head)))
            good_tops = tops[ok]
            tails.extend((good_tops[k], good_tops[k + 1]) for k in range(len(good_tops) - 1))
            mid = good_tops[len(good_tops) // 2] - down * 0.015 * size
            labels.append(f"{load.get('name', '?')}: {pressure_text(load)}")
            label_points.append([float(mid[0]), float(mid[1]), 0.06])
            self.drawn_loads.append(str(load.get("name", "?")))
        if arrows:
            self._add(_lines(arrows), color=LOAD_COLOR, line_width=2, name="load-arrows", render=False,
                      lighting=False, pickable=False)
        if tails:
            self._add(_lines(tails), color=LOAD_COLOR, line_width=2, name="load-tails", render=False,
                      lighting=False, pickable=False)
        if labels:
            pl.add_point_labels(np.array(label_points), labels, name="load-labels", font_size=10,
                                text_color=LOAD_COLOR, shape=None, show_points=False, always_visible=True,
                                render=False, reset_camera=False, justification_horizontal="center",
                                justification_vertical="bottom")
        seismic = get_path(self.doc.data, f"stages.{self.loads_stage}.seismic")
        if isinstance(seismic, dict) and any(isinstance(seismic.get(k), (int, float)) for k in ("k_h", "k_v")):
            k_h, k_v = seismic.get("k_h", 0.0), seismic.get("k_v", 0.0)
            towards = seismic.get("towards", "out-of-slope")
            sign = {"left": -1.0, "right": 1.0}.get(towards)
            if sign is None and polygons:
                try:
                    sign = out_of_slope(polygons, down)
                except ValueError:
                    sign = None
            across = np.array([-down[1], down[0]])
            start = np.array([box[0] + 0.02 * size, box[3] + 0.05 * size])  # above the domain's top left
            text = f"seismic k_h = {format_number(k_h)}, k_v = {format_number(k_v)} ({towards})"
            if sign is not None and isinstance(k_h, (int, float)) and k_h > 0:
                tip = start + sign * across * 0.08 * size
                back = tip - sign * across * 0.015 * size
                self._add(_lines([(start, tip), (back + down * 0.008 * size, tip), (back - down * 0.008 * size, tip)]),
                          color=LOAD_COLOR, line_width=3, name="seismic-arrow", render=False, lighting=False,
                          pickable=False)
            pl.add_point_labels(np.array([[start[0], start[1] + 0.02 * size, 0.06]]), [text], name="seismic-labels",
                                font_size=10, text_color=LOAD_COLOR, shape=None, show_points=False,
                                always_visible=True, render=False, reset_camera=False,
                                justification_horizontal="left", justification_vertical="bottom")
            self.drawn_loads.append("seismic")

    def _hatch_step(self, poly: np.ndarray) -> float:
        """The spacing of a structure's hatching, m: about 1/60 of the domain's larger side, closer
        in a structure too thin for three lines at that spacing (down to 1/400 of the domain)."""
        box = self._domain_box()
        size = max(box[1] - box[0], box[3] - box[2]) if box is not None else 1.0
        extent = float(np.min(np.ptp(poly, axis=0)))
        return max(min(size / 60.0, extent / 3.0), size / 400.0)

    def _draw_targets(self) -> None:
        """Line targets as vertical lines over the domain's height, point targets as markers, with names."""
        import pyvista as pv

        pl = self.plotter
        for name in ("target-lines", "target-points", "target-labels-labels", "target-selected"):
            pl.remove_actor(name, render=False)
        box = self._domain_box()
        if box is None:
            return
        lines, points, labels, label_points, selected = [], [], [], [], []
        pad = 0.02 * (box[3] - box[2])
        for i, target in enumerate(self._polygons("targets")):
            where = target_place(target)
            if where is None:
                continue
            x, y = where
            name = str(target.get("name", "?"))
            if y is None:
                segment = (np.array([x, box[2]]), np.array([x, box[3]]))
                lines.append(segment)
                label_points.append([x, box[3] + pad, 0.05])
            else:
                segment = None
                points.append([x, y])
                label_points.append([x, y + pad, 0.05])
            labels.append(name)
            if self.doc.selection.target == i:
                selected.append((segment, (x, y)))
        if lines:
            self._add(_lines(lines), color=TARGET_COLOR, line_width=2, name="target-lines", render=False,
                      lighting=False)
        if points:
            self._add(pv.PolyData(_points3(np.array(points), 0.04)), color=TARGET_COLOR, point_size=12,
                      render_points_as_spheres=True, name="target-points", render=False)
        if labels:
            pl.add_point_labels(np.array(label_points), labels, name="target-labels", font_size=10,
                                text_color=TARGET_COLOR, shape=None, show_points=False, always_visible=True,
                                render=False, reset_camera=False, justification_horizontal="center")
        for segment, (x, y) in selected:
            if segment is not None:
                self._add(_lines([segment]), color="#fbbc04", line_width=5, name="target-selected", render=False,
                          lighting=False)
            else:
                self._add(pv.PolyData(_points3(np.array([[x, y]]), 0.045)), color="#fbbc04", point_size=17,
                          render_points_as_spheres=True, name="target-selected", render=False)

    def _update_legend(self) -> None:
        names = self.doc.material_names
        parts = [f'<span style="color:{material_color(i)}; font-size:14px">■</span>&nbsp;{n}'
                 for i, n in enumerate(names)]
        sides = "".join(
            f'&nbsp;&nbsp;<span style="color:{c}">━</span>&nbsp;{k}' for k, (c, _w) in BOUNDARY_STYLE.items())
        count = len(self.doc.get("bodies", []))
        extra = ""
        structures, targets = len(self._polygons("structures")), len(self._polygons("targets"))
        if structures:
            extra += (f' &nbsp;<span style="color:{STRUCTURE_COLOR}; font-size:14px">▨</span>&nbsp;'
                      f'{structures} structure{"" if structures == 1 else "s"}')
        if targets:
            extra += (f' &nbsp;<span style="color:{TARGET_COLOR}">┃</span>&nbsp;'
                      f'{targets} target{"" if targets == 1 else "s"}')
        if self._water_line(0) is not None:
            from app.render import FREE_WATER_COLOR, WATER_LINE_COLOR

            extra += (f' &nbsp;<span style="color:{WATER_LINE_COLOR}">━</span>&nbsp;phreatic line'
                      f' &nbsp;<span style="color:{FREE_WATER_COLOR}; font-size:14px">■</span>&nbsp;free water')
        if self.drawn_loads:
            extra += (f' &nbsp;<span style="color:{LOAD_COLOR}">⇓</span>&nbsp;loads of stage '
                      f'{(self.loads_stage or 0) + 1}')
        grid = f"&nbsp;&nbsp;&nbsp;&nbsp;grid lines every {self.grid_step} cells" if self.grid_step > 1 else ""
        self.legend.setText(f"<b>Materials</b>&nbsp; {'&nbsp;&nbsp;'.join(parts) or 'none'}"
                            f" &nbsp;&nbsp;&nbsp;<b>Boundaries</b>{sides}"
                            f" &nbsp;&nbsp;&nbsp;{count} bod{'y' if count == 1 else 'ies'}{extra}"
                            + (f", {self.preview_count:,} particles" if self.show_particles and self.preview_count
                               else "")
                            + grid)

    def _draw_draft(self) -> None:
        import pyvista as pv

        pl = self.plotter
        pl.remove_actor("draft-line", render=False)
        pl.remove_actor("draft-points", render=False)
        if self.mode != "draw" or not self.draft:
            return
        pts = np.array(self.draft, dtype=float)
        chain = list(pts)
        if self._cursor is not None:
            chain.append(self._cursor)
        if len(chain) >= 2:
            seg = [(chain[k], chain[k + 1]) for k in range(len(chain) - 1)]
            self._add(_lines(seg), color="#d93025" if self._draft_crosses() else "#1a73e8", line_width=2.5,
                        name="draft-line", render=False, lighting=False)
        self._add(pv.PolyData(_points3(pts, 0.03)), color="#1a73e8", point_size=10,
                    render_points_as_spheres=True, name="draft-points", render=False)

    def _draft_crosses(self) -> bool:
        from geometry.polygons import self_intersections

        if len(self.draft) < 3 or self.draw_kind == "water":
            return False
        try:
            return bool(self_intersections(np.array(self.draft, dtype=float)))
        except ValueError:
            return False

    def _draw_particles(self) -> None:
        """Seed the bodies as a run would and show the points (skipped for huge counts)."""
        import pyvista as pv

        if self._closed:
            return
        pl = self.plotter
        pl.remove_actor("particles", render=False)
        self.preview_count = 0
        if self.show_particles:
            positions, material = self._seed()
            if positions is not None and len(positions):
                self.preview_count = len(positions)
                cloud = pv.PolyData(_points3(positions, 0.01))
                colors = np.array([_rgb(material_color(m)) for m in range(max(1, int(material.max()) + 1))])
                cloud.point_data["rgb"] = (colors[material] * 0.85 * 255).astype(np.uint8)
                size = max(1.0, min(6.0, self._spacing_pixels() * 0.5))
                self._add(cloud, scalars="rgb", rgb=True, point_size=size, name="particles",
                          show_scalar_bar=False, lighting=False, pickable=False)
        self._update_legend()
        pl.render()

    def _resolved(self, seed: bool) -> Any:
        """The run the project stands for (:func:`projects.build.resolve`: preset and all), or
        None while the project has problems."""
        project = self.doc.project
        if project is None:
            return None
        from projects.build import resolve
        from projects.schema import ProjectError

        try:
            return resolve(project, seed=seed)
        except (ProjectError, ValueError, ArithmeticError):
            return None

    def _spacing_pixels(self) -> float:
        resolved = self._resolved(seed=False)
        if resolved is None:
            return 2.0
        return resolved.spacing_m / max(self.pixel_size_m(), 1e-12)

    def _seed(self) -> tuple[np.ndarray | None, np.ndarray]:
        """The particles the run will start from (seeded by :func:`projects.build.resolve`)."""
        empty = np.zeros(0, dtype=int)
        resolved = self._resolved(seed=False)
        if resolved is None:
            self.message.emit("particle preview: fix the project's problems first")
            self._preview_refused = True
            return None, empty
        if self._preview_refused:
            self._preview_refused = False
            self.message.emit("")  # the problems are fixed: the refusal no longer holds
        if resolved.particle_count > MAX_SEEDED_PARTICLES:
            self.message.emit(f"particle preview skipped: about {resolved.particle_count:,} particles")
            return None, empty
        try:
            particles = self.doc.seeded_run().particles  # one seeding per edit, shared with the Run panel
        except (ValueError, ArithmeticError) as err:
            self.message.emit(f"particle preview: {err}")
            return None, empty
        except Exception as err:  # noqa: BLE001 - a preview must never take the workbench down
            self.message.emit(f"particle preview: {err}")
            return None, empty
        names = resolved.material_names
        order = np.array([self._material_index(name) for name in names], dtype=int)
        material = np.maximum(order[np.asarray(particles.material_ids, dtype=int)], 0)
        return np.asarray(particles.positions_m), material

    def set_show_particles(self, on: bool) -> None:
        self.show_particles = bool(on)
        self._draw_particles()

    # -- modes --------------------------------------------------------------------------------

    def set_mode(self, mode: str, kind: str | None = None, slot: int | None = None) -> None:
        """``"select"`` (pick, drag vertices, pan) or ``"draw"`` (click vertices of a new polygon of
        ``kind``: ``"bodies"`` or ``"structures"``; by default what is being drawn, else a body; or
        ``"water"``: water line ``slot``, clicked from left to right, which it replaces)."""
        if kind is None:
            kind = self.draw_kind if mode == self.mode else "bodies"
        if kind not in (*POLYGON_KINDS, "water"):
            raise ValueError(f"cannot draw {kind!r}: one of {', '.join((*POLYGON_KINDS, 'water'))}")
        slot = self.draw_slot if slot is None else int(slot)
        if mode == self.mode and kind == self.draw_kind and (kind != "water" or slot == self.draw_slot):
            return
        self.draw_kind = kind
        self.draw_slot = slot
        self.mode = mode
        self.draft = []
        self._cursor = None
        self.plotter.setCursor(Qt.CursorShape.CrossCursor if mode == "draw" else Qt.CursorShape.ArrowCursor)
        if mode == "draw" and kind == "water":
            self.message.emit(f"Drawing the {water_line_noun(slot)}. Click its points from left to right; "
                              "double-click or Enter to finish; Backspace removes the last, Esc cancels")
        elif mode == "draw":
            noun = "body" if kind == "bodies" else "structure"
            self.message.emit(f"Drawing a {noun}. Click to add vertices; click the first vertex, double-click or Enter to close; "
                              "Backspace removes the last, Esc cancels")
        self._draw_draft()
        self.plotter.render()
        self.modeChanged.emit(mode)

    def set_snap(self, on: bool) -> None:
        self.snap = bool(on)

    def snapped(self, xy: np.ndarray, moving: tuple[int, int] | None = None) -> np.ndarray:
        """Snap to a nearby vertex of a body (shared edges), else to the grid when snapping is on.

        ``moving`` (body, vertex) or (kind, index, vertex) is the vertex being dragged, which must
        not snap to itself. Vertices of bodies and structures are snapped to alike.
        """
        tol = PICK_PIXELS * self.pixel_size_m()
        if moving is not None and len(moving) == 2:
            moving = ("bodies", *moving)
        for kind in POLYGON_KINDS:
            for i, body in enumerate(self._polygons(kind)):
                poly = _as_points(body.get("polygon_m"))
                if poly is None or not len(poly):
                    continue
                d = np.hypot(*(poly - xy).T)
                if moving is not None and moving[0] == kind and moving[1] == i:
                    # its own neighbours are not targets either: snapping onto them collapses an edge
                    count = len(poly)
                    for k in (moving[2] - 1, moving[2], moving[2] + 1):
                        d[k % count] = np.inf
                k = int(np.argmin(d))
                if d[k] <= tol:
                    return poly[k].copy()
        if not self.snap:
            return xy
        cell = self.doc.get("domain.cell_size_m")
        origin = _as_points([self.doc.get("domain.origin_m", [0.0, 0.0])])
        if not isinstance(cell, (int, float)) or cell <= 0 or origin is None:
            return xy
        # snap to half cells: fine enough for slopes, still on the particle lattice lines
        step = float(cell) / 2.0
        o = origin[0]
        snapped = o + np.round((xy - o) / step) * step
        return np.round(snapped, 12)

    # -- edits from the mouse -------------------------------------------------------------------

    def add_draft_point(self, xy: Any) -> None:
        """Add a vertex to the polygon being drawn (closes it when ``xy`` is its first vertex)."""
        p = np.asarray(xy, dtype=float)
        if self.draw_kind == "water":
            if self.draft and p[0] <= self.draft[-1][0]:
                self.message.emit(f"A water line goes from left to right: click right of x = "
                                  f"{format_number(self.draft[-1][0])} m")
                return
            self.draft.append([float(p[0]), float(p[1])])
            self._draw_draft()
            self.plotter.render()
            return
        if len(self.draft) >= 3:
            first = np.asarray(self.draft[0])
            if np.hypot(*(p - first)) <= PICK_PIXELS * self.pixel_size_m():
                self.close_draft()
                return
        if self.draft and np.allclose(self.draft[-1], p):
            return
        self.draft.append([float(p[0]), float(p[1])])
        self._draw_draft()
        self.plotter.render()

    def close_draft(self) -> bool:
        """Turn the drawn polygon into a new body of the selected (or first) material, or a new
        structure (slip contact) when a structure is being drawn; or the water line being drawn."""
        if self.draw_kind == "water":
            return self._close_water()
        if len(self.draft) < 3:
            self.message.emit(f"A {'body' if self.draw_kind == 'bodies' else 'structure'} needs at least 3 vertices")
            return False
        if self.draw_kind == "structures":
            return self._close_structure()
        names = self.doc.material_names
        current = self.doc.selection.body
        bodies = self.doc.get("bodies", [])
        material = bodies[current].get("material") if current is not None and current < len(bodies) else None
        material = material or (names[0] if names else "soil")
        taken = {b.get("name") for b in bodies}
        k = len(bodies) + 1
        while f"body-{k}" in taken:
            k += 1
        body = {"name": f"body-{k}", "material": material, "polygon_m": [list(p) for p in self.draft]}
        self.draft = []
        self._cursor = None
        self.doc.edit(f"draw body {body['name']}", lambda d: d.setdefault("bodies", []).append(body))
        self.doc.selection.set(len(self.doc.get("bodies", [])) - 1)
        self.set_mode("select")
        return True

    def _close_structure(self) -> bool:
        items = self._polygons("structures")
        taken = {b.get("name") for b in items}
        k = len(items) + 1
        while f"structure-{k}" in taken:
            k += 1
        item = {"name": f"structure-{k}", "polygon_m": [list(p) for p in self.draft], "contact": "slip"}
        self.draft = []
        self._cursor = None
        self.doc.edit(f"draw structure {item['name']}", lambda d: d.setdefault("structures", []).append(item))
        self.doc.selection.select("structures", len(self._polygons("structures")) - 1)
        self.set_mode("select")
        return True

    def _close_water(self) -> bool:
        if len(self.draft) < 2:
            self.message.emit("A water line needs at least 2 points")
            return False
        slot, line = self.draw_slot, [list(p) for p in self.draft]
        self.draft = []
        self._cursor = None
        set_water_line(self.doc, slot, line, f"draw the {water_line_noun(slot)}")
        self.doc.selection.select("water", slot)
        self.set_mode("select")
        return True

    def cancel_draft(self) -> None:
        self.draft = []
        self._draw_draft()
        self.plotter.render()

    def _nearest_vertex(self, xy: np.ndarray) -> tuple[str, int, int] | None:
        """(kind, index, vertex) of the polygon vertex within a few pixels of ``xy``, or None."""
        tol = PICK_PIXELS * self.pixel_size_m()
        order = [(kind, i) for kind in POLYGON_KINDS for i in range(len(self._polygons(kind)))]
        sel = self.doc.selection
        if (sel.kind, sel.index) in order:  # the selected polygon wins ties
            order.remove((sel.kind, sel.index))
            order.insert(0, (sel.kind, sel.index))
        best: tuple[float, str, int, int] | None = None
        for kind, i in order:
            poly = _as_points(self._polygons(kind)[i].get("polygon_m"))
            if poly is None or not len(poly):
                continue
            d = np.hypot(*(poly - xy).T)
            k = int(np.argmin(d))
            if d[k] <= tol and (best is None or d[k] < best[0] - 1e-12):
                best = (float(d[k]), kind, i, k)
        if best is None or sel.kind == "water":  # a selected water line wins over polygons
            for slot in sorted(self.shown_water_slots(), key=lambda k: k != sel.index):
                line = self._water_line(slot)
                d = np.hypot(*(line - xy).T)
                k = int(np.argmin(d))
                if d[k] <= tol:
                    return "water", slot, k
        return None if best is None else (best[1], best[2], best[3])

    def _polygon_at(self, xy: np.ndarray) -> tuple[str, int] | None:
        """(kind, index) of the body (on top) or else structure under ``xy``."""
        from geometry.polygons import points_in_polygon

        for kind in POLYGON_KINDS:
            items = self._polygons(kind)
            for i in reversed(range(len(items))):  # the later body is painted on top
                poly = _as_points(items[i].get("polygon_m"))
                if poly is not None and len(poly) >= 3:
                    try:
                        if bool(points_in_polygon(xy[None, :], poly)[0]):
                            return kind, i
                    except ValueError:
                        continue
        return None

    def _body_at(self, xy: np.ndarray) -> int | None:
        hit = self._polygon_at(xy)
        return hit[1] if hit is not None and hit[0] == "bodies" else None

    def _target_at(self, xy: np.ndarray) -> int | None:
        """The target whose line or marker is within a few pixels of ``xy``."""
        tol = PICK_PIXELS * self.pixel_size_m()
        best: tuple[float, int] | None = None
        for i, target in enumerate(self._polygons("targets")):
            where = target_place(target)
            if where is None:
                continue
            d = abs(xy[0] - where[0]) if where[1] is None else float(np.hypot(xy[0] - where[0], xy[1] - where[1]))
            if d <= tol and (best is None or d < best[0]):
                best = (d, i)
        return None if best is None else best[1]

    def move_target(self, index: int, xy: Any, merge_key: str | None = None) -> None:
        """Move target ``index`` to ``xy`` (a line target only along x)."""
        x, y = float(xy[0]), float(xy[1])

        def mutate(d: dict[str, Any]) -> None:
            target = d["targets"][index]
            if target.get("point_m") is not None:
                target["point_m"] = [x, y]
            else:
                target["x_m"] = x

        name = self.doc.get(f"targets.{index}.name", index)
        self.doc.edit(f"move target {name}", mutate, merge_key)

    def move_vertex(self, body: int, vertex: int, xy: Any, merge_key: str | None = None,
                    kind: str = "bodies") -> None:
        """Move vertex ``vertex`` of polygon ``body`` of ``kind`` (bodies or structures) to ``xy``."""
        x, y = float(xy[0]), float(xy[1])

        def mutate(d: dict[str, Any]) -> None:
            d[kind][body]["polygon_m"][vertex] = [x, y]

        name = self.doc.get(f"{kind}.{body}.name", body)
        self.doc.edit(f"move vertex {vertex + 1} of {name}", mutate, merge_key)  # as the panel's table rows

    def delete_selected_vertex(self) -> None:
        sel = self.doc.selection
        kind, index, vertex = sel.kind, sel.index, sel.vertex
        if kind == "water" and index is not None and vertex is not None:
            path = water_line_path(index)
            self.doc.edit(f"delete vertex {vertex + 1} of the {water_line_noun(index)}",
                          lambda d: get_path(d, path).pop(vertex))
            return
        if kind not in POLYGON_KINDS or index is None or vertex is None:
            return
        self.doc.edit("delete vertex", lambda d: d[kind][index]["polygon_m"].pop(vertex))

    # -- Qt events ------------------------------------------------------------------------------

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt's name
        if obj is not self.plotter or self._closed:
            return False
        kind = event.type()
        if kind == QEvent.Type.MouseMove:
            return self._mouse_move(event)  # type: ignore[arg-type]
        if kind == QEvent.Type.MouseButtonPress and _left(event):
            return self._mouse_press(event)  # type: ignore[arg-type]
        if kind == QEvent.Type.MouseButtonDblClick and _left(event):
            if self.mode == "draw":
                self.close_draft()
                return True
            return self._drag is not None
        if kind == QEvent.Type.MouseButtonRelease and _left(event):
            if self._drag is not None:
                self._drag = None
                return True
            if self.mode != "draw":
                self._auto_fit = False  # the left button pans in the select mode
            return self.mode == "draw"
        if kind == QEvent.Type.KeyPress:
            return self._key(event)  # type: ignore[arg-type]
        if kind in (QEvent.Type.Wheel, QEvent.Type.MouseButtonRelease):
            self._auto_fit = False  # the user panned or zoomed
        return False

    def _mouse_move(self, event: QMouseEvent) -> bool:
        xy = self.widget_to_world(event.position())
        self.cursorMoved.emit(float(xy[0]), float(xy[1]))
        if self._drag is not None:
            kind, index, vertex = self._drag
            key = f"drag-{self._drag_count}"
            if kind == "targets":
                self.move_target(index, self.snapped(xy), merge_key=key)
            elif kind == "water":
                self.move_water_vertex(index, vertex, self.snapped(xy), merge_key=key)
            else:
                self.move_vertex(index, vertex, self.snapped(xy, moving=self._drag), merge_key=key, kind=kind)
            return True
        if self.mode == "draw" and self.draft:
            self._cursor = self.snapped(xy)
            self._draw_draft()
            self.plotter.render()
        return False

    def _mouse_press(self, event: QMouseEvent) -> bool:
        xy = self.widget_to_world(event.position())
        self.plotter.setFocus()
        if self.mode == "draw":
            self.add_draft_point(self.snapped(xy))
            return True
        hit = self._nearest_vertex(xy)
        if hit is not None:
            self.doc.selection.select(*hit)
            self._drag = hit
            self._drag_count += 1
            return True
        target = self._target_at(xy)
        if target is not None:
            self.doc.selection.select("targets", target)
            self._drag = ("targets", target, None)
            self._drag_count += 1
            return True
        polygon = self._polygon_at(xy)
        if polygon is not None:
            self.doc.selection.select(*polygon)
            return False  # a drag from inside a body still pans
        self.doc.selection.set(None)
        return False

    def _key(self, event: QKeyEvent) -> bool:
        key = event.key()
        if self.mode == "draw":
            if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
                self.close_draft()
                return True
            if key == Qt.Key.Key_Escape:
                self.cancel_draft()
                self.set_mode("select")
                return True
            if key == Qt.Key.Key_Backspace and self.draft:
                self.draft.pop()
                self._draw_draft()
                self.plotter.render()
                return True
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            self.delete_selected_vertex()
            return True
        # pyvista's own keys (q closes, v isometric, ...) make no sense in the embedded view
        return key not in (Qt.Key.Key_Plus, Qt.Key.Key_Minus)
