"""The Factor-of-safety tab of a strength-reduction run: the factor with its bracket and the
criterion that decided, Bishop's factor beside it, the F-displacement (knee) curve of the trials
and the mechanism (plastic strain of the mechanism frame with Bishop's critical circle).

Read from ``summary.json`` (``factor_of_safety``, ``limit_equilibrium``; docs/project-format.md)
and the mechanism frame of the results folder; the same picture as ``runout render --mechanism``
(:func:`app.render.render_mechanism`), drawn in the window.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from app.gui.hazard_view import format_value

logger = logging.getLogger(__name__)


def fos_text(summary: dict[str, Any]) -> str:
    """The factor of safety, its bracket and criterion, and Bishop's factor, as rich text."""
    fos = summary.get("factor_of_safety") or {}
    le = summary.get("limit_equilibrium") or {}
    value = fos.get("value")
    head = (f"<b>Factor of safety (strength reduction): {value:.3f}</b>"
            if value is not None else "<b>Factor of safety: not bracketed</b>")
    parts = [head,
             f"bracket [{format_value(fos.get('lower'), digits=4)}, {format_value(fos.get('upper'), digits=4)}]"
             f" (tolerance {format_value(fos.get('tolerance'))}), decided by the {fos.get('criterion', '?')} "
             f"criterion, {len(fos.get('trials') or [])} trials"]
    if le.get("factor_of_safety") is not None:
        circle = le.get("circle") or {}
        centre = circle.get("centre_m") or [float("nan"), float("nan")]
        parts.append(f"Bishop's simplified method: <b>{le['factor_of_safety']:.3f}</b> "
                     f"(Fellenius {format_value(le.get('fellenius_factor_of_safety'), digits=4)}; critical circle "
                     f"centre ({centre[0]:.2f}, {centre[1]:.2f}) m, radius "
                     f"{format_value(circle.get('radius_m'), 'm', 3)}, {le.get('circles_tried', '?')} circles)")
    elif le.get("message"):
        parts.append(f"Limit equilibrium: {le['message']}")
    if fos.get("runout_factor") is not None:
        parts.append(f"run-out stage from F = {format_value(fos['runout_factor'], digits=4)}: largest displacement "
                     f"{format_value(fos.get('runout_max_displacement_m'), 'm', 3)}")
    if fos.get("message"):
        parts.append(str(fos["message"]))
    return "<br>".join(parts)


class FosView(QWidget):
    """Factor of safety, knee curve and mechanism of a strength-reduction results folder."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
        from matplotlib.figure import Figure

        self.summary: dict[str, Any] | None = None
        self._key: tuple[str, int] | None = None
        self.label = QLabel("Not a strength-reduction run.")
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        self.label.setStyleSheet("padding: 4px;")
        self.figure = Figure(figsize=(10.0, 4.5))
        self.canvas = FigureCanvasQTAgg(self.figure)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.label)
        layout.addWidget(self.canvas, 1)

    def show_results(self, results: Any) -> bool:
        """Show the factor of safety of open results; False (and cleared) when there is none."""
        summary = dict(results.summary) if results is not None else {}
        if not summary.get("factor_of_safety"):
            self.summary = None
            self._key = None
            self.label.setText("Not a strength-reduction run.")
            self.figure.clear()
            self.canvas.draw_idle()
            return False
        key = (str(results.path), len(results))
        if key == self._key and summary == self.summary:
            return True
        self.summary, self._key = summary, key
        self.label.setText(fos_text(summary))
        self._draw(results, summary)
        return True

    def _draw(self, results: Any, summary: dict[str, Any]) -> None:
        fos = summary["factor_of_safety"]
        le = summary.get("limit_equilibrium") or {}
        fig = self.figure
        fig.clear()
        ax, knee = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.6, 1]})
        frame = fos.get("mechanism_frame")
        xy = None
        if frame is not None and int(frame) < len(results):
            try:
                arrays = results.frame(int(frame))
                keep = arrays["active"]
                xy = np.asarray(arrays["positions"])[keep]
                eps = np.asarray(arrays.get("plastic_strain", np.zeros(len(keep))))[keep]
                width = max(float(np.ptp(xy[:, 0])), 1e-9)
                spacing = float(summary.get("particle_spacing_m") or 0.0)
                dots = ax.scatter(xy[:, 0], xy[:, 1], c=eps, s=max(1.0, 2500.0 * spacing / width), cmap="inferno",
                                  marker="s", linewidths=0)
                bar = fig.colorbar(dots, ax=ax, orientation="horizontal", fraction=0.05, pad=0.14, aspect=40)
                bar.set_label("equivalent plastic strain", fontsize=8)
                bar.ax.tick_params(labelsize=7)
                ax.set_title(f"mechanism at F = {fos['upper']:.3f} (frame {int(frame)})", fontsize=9)
            except Exception:  # noqa: BLE001 - a frame being written: the circle is drawn alone
                logger.debug("cannot draw the mechanism frame", exc_info=True)
                xy = None
        circle = le.get("circle")
        if circle:
            cx, cy = circle["centre_m"]
            t = np.linspace(np.pi, 2.0 * np.pi, 361)
            ax.plot(cx + circle["radius_m"] * np.cos(t), cy + circle["radius_m"] * np.sin(t), "c--", lw=1.5,
                    label=f"Bishop critical circle, F = {le['factor_of_safety']:.3f}")
        if fos.get("monitor_point_m"):
            ax.plot(*fos["monitor_point_m"], "o", mfc="none", mec="lime", ms=10, label="monitor point")
        from app.report import structure_patches

        structures = summary.get("structures") or []
        structure_patches(ax, structures)  # the walls and dams the mechanism runs against
        if xy is not None and len(xy):
            box = np.vstack([xy, *[np.asarray(st.get("polygon_m") or np.zeros((0, 2)), dtype=float).reshape(-1, 2)
                                   for st in structures]])
            pad = 0.05 * max(np.ptp(box[:, 0]), np.ptp(box[:, 1]))
            ax.set_xlim(box[:, 0].min() - pad, box[:, 0].max() + pad)
            ax.set_ylim(box[:, 1].min() - pad, box[:, 1].max() + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)", fontsize=8)
        ax.set_ylabel("y (m)", fontsize=8)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=7)  # where it hides the fewest particles (the air, not the toe)
        trials = sorted(fos.get("trials") or [], key=lambda tr: tr["factor"])
        for verdict, style in (("stable", "bo"), ("failed", "rx")):
            pts = [(tr["factor"], tr["monitor_displacement_m"]) for tr in trials if tr["verdict"] == verdict]
            if pts:
                knee.plot(*zip(*pts), style, label=verdict)
        if trials:
            knee.plot([tr["factor"] for tr in trials], [tr["monitor_displacement_m"] for tr in trials], "k-", lw=0.5)
        if fos.get("lower") is not None and fos.get("upper") is not None:
            knee.axvspan(fos["lower"], fos["upper"], color="0.85", label="bracket")
        if fos.get("value") is not None:
            knee.axvline(fos["value"], color="k", ls=":", label=f"F = {fos['value']:.3f}")
        if le.get("factor_of_safety") is not None:
            knee.axvline(le["factor_of_safety"], color="c", ls="--", label="Bishop")
        knee.set_xlabel("trial factor F", fontsize=8)
        knee.set_ylabel("monitor displacement (m)", fontsize=8)
        knee.set_title("F - displacement of the trials", fontsize=9)
        knee.grid(True, color="#e6e6e6", linewidth=0.6)
        knee.legend(fontsize=7)
        for a in (ax, knee):
            a.tick_params(labelsize=8)
        fig.subplots_adjust(left=0.05, right=0.98, top=0.93, bottom=0.1, wspace=0.18)
        self.canvas.draw_idle()

    def close_view(self) -> None:
        self.figure.clear()
