"""Pictures of the real workbench window for the documentation.

Run under a display (Xvfb on a server)::

    xvfb-run -a -s "-screen 0 1920x1200x24" python -m app.gui.screenshots docs/screenshots

It opens the shipped examples, runs one on the CPU (as a child process, like every run of the
workbench) and saves ``prepare.png`` (the model of the slope example with a preset: the run
panel says what will run), ``running.png`` (a run under way, live from its results folder) and
``results.png`` (the inspector with monitoring points and a cross-section). The window is
grabbed by Qt, embedded VTK views included.
"""

from __future__ import annotations

import logging
import sys
import tempfile
import time
from pathlib import Path

from app.gui import configure_environment

logger = logging.getLogger(__name__)

EXAMPLES = Path(__file__).resolve().parents[2] / "projects" / "examples"
SIZE = (1600, 1000)


def _settle(app: object, seconds: float = 0.3) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        app.processEvents()  # type: ignore[attr-defined]
        time.sleep(0.01)


def make_screenshots(out_dir: Path) -> list[Path]:
    """Write the three pictures into ``out_dir``; return their paths."""
    configure_environment()
    from PySide6.QtWidgets import QApplication

    from app.gui.main_window import MainWindow
    from app.gui.settings import MaterialLibrary, Settings
    from projects.document import apply_overrides, load_project, save_project

    out_dir.mkdir(parents=True, exist_ok=True)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    work = Path(tempfile.mkdtemp(prefix="runout-shots-"))
    window = MainWindow(settings=Settings(work / "config"), library=MaterialLibrary(work / "config"))
    window.resize(*SIZE)
    window.show()
    _settle(app)
    written = []

    # prepare: the layered slope of the Sun & Song example, its first body selected, with the
    # "draft" preset chosen: the run panel says what will run instead of the panels' values
    window.open_project(EXAMPLES / "slope_sun_song_2015.toml", ask=False)

    def draft(d: dict) -> None:
        d["numerics"].pop("time_step_s", None)
        d["numerics"]["preset"] = "draft"

    window.doc.edit("preset draft", draft)
    window.panels.setCurrentWidget(window.bodies_panel)
    window.doc.selection.set(0, 3)
    window.run_panel.update_estimate()
    _settle(app, 0.8)
    written.append(out_dir / "prepare.png")
    window.grab().save(str(written[-1]))

    # running: the aluminium-bar collapse of the paper at half its resolution and five times its
    # time step (5000 particles), so that it runs in well under a minute on a CPU
    project = apply_overrides(load_project(EXAMPLES / "bui2008_aluminium_bars.toml"), [
        "domain.cell_size_m=0.004", "numerics.time_step_s=1e-4", "stages.1.duration_s=0.6",
        "output.interval_s=0.02", "numerics.arch=cpu"])
    path = work / "bui2008_coarse.toml"
    save_project(project, path)
    window.open_project(path, ask=False)
    window.panels.setCurrentWidget(window.materials_panel)
    window.start_run()
    fraction = 0.0
    end = time.perf_counter() + 300
    while window.running and fraction < 0.4 and time.perf_counter() < end:
        app.processEvents()
        time.sleep(0.02)
        fraction = window.run_panel.progress.value() / 1000.0
    _settle(app, 0.6)
    written.append(out_dir / "running.png")
    window.grab().save(str(written[-1]))
    window.wait_for_run(600)

    # results: the inspector half way through the run, monitoring points at the block's upper
    # right corner and half way down its right side, and a horizontal cross-section
    view = window.results_view
    if view.results is not None:
        view.controls.slider.setValue(int(0.5 * (len(view.results) - 1)))
        view.set_field("displacement")
        frame = view.results.frame(0)
        x1, y1 = frame["positions"].max(axis=0)
        view.add_monitor(float(x1), float(y1), "crest")
        view.add_monitor(float(x1), 0.5 * float(y1), "mid-height")
        view.set_section(0.0, 0.005, float(x1) * 2.5, 0.005)
        # by its title: the tabs' order changes as tabs are added (the contact forces' tab moved it)
        titles = [view.side.tabText(i) for i in range(view.side.count())]
        view.side.setCurrentIndex(titles.index("Monitoring points"))
    _settle(app, 0.8)
    written.append(out_dir / "results.png")
    window.grab().save(str(written[-1]))
    window.shutdown()
    window.close()
    return written


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0]) if args else Path("docs/screenshots")
    logging.basicConfig(level=logging.INFO)
    for path in make_screenshots(out):
        logger.info("wrote %s", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
