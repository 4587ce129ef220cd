"""Pictures of the Hazard, Factor-of-safety and Sweep tabs for the documentation.

Run under a display (Xvfb on a server), after a hazard run and a strength-reduction run::

    runout run hazard.toml --out hazard.results          # e.g. the tiny column with targets
    runout run projects/examples/slope_fos.toml --out slope_fos.results
    xvfb-run -a -s "-screen 0 1920x1200x24" python -m app.gui.analysis_screenshots docs/screenshots \\
        --hazard hazard.results --fos slope_fos.results --project hazard.toml --runs 6 \\
        --set 'numerics.arch="cpu"; stages.1.duration_s=0.2'

It saves ``hazard.png`` and ``fos.png`` (the tabs on those folders), then defines a sweep of the
project over the friction angle in the Sweep dialog (``sweep_dialog.png``), starts it (a child
``runout sweep``, 2 workers) and saves ``sweep.png`` when it has finished (``--sweep FOLDER``:
shows that sweep folder instead). The window is grabbed by Qt.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from app.gui import configure_environment

SIZE = (1600, 1000)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--hazard", type=Path, required=True, help="a results folder with hazard files")
    parser.add_argument("--fos", type=Path, help="a strength-reduction results folder")
    parser.add_argument("--project", type=Path, help="the project to sweep over its friction angle")
    parser.add_argument("--sweep", type=Path, help="show this sweep folder instead of running one")
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--set", dest="fixed", default='numerics.arch="cpu"',
                        help='fixed overrides of the sweep, ";"-separated (numerics.arch="cpu")')
    parser.add_argument("--timeout", type=float, default=900.0, help="longest wait for the sweep, s")
    args = parser.parse_args(argv)
    configure_environment()
    from PySide6.QtWidgets import QApplication

    from app.gui.main_window import MainWindow
    from app.gui.settings import MaterialLibrary, Settings
    from app.gui.sweep_dialog import SweepDialog

    app = QApplication.instance() or QApplication(sys.argv[:1])

    def settle(seconds: float = 0.5) -> None:
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            app.processEvents()
            time.sleep(0.01)

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    config = tempfile.mkdtemp()
    win = MainWindow(settings=Settings(config), library=MaterialLibrary(config))
    win.resize(*SIZE)
    win.show()
    settle(1.0)
    written = []
    try:
        win.open_results(args.hazard)
        win.tabs.setCurrentWidget(win.hazard_view)
        settle(1.5)
        win.grab().save(str(out / "hazard.png"))
        written.append(out / "hazard.png")
        if args.fos:
            win.open_results(args.fos)
            win.tabs.setCurrentWidget(win.fos_view)
            settle(1.5)
            win.grab().save(str(out / "fos.png"))
            written.append(out / "fos.png")
        if args.sweep:
            if args.project:
                win.open_project(args.project, ask=False)
            win.open_sweep(args.sweep)
            settle(1.5)
            win.grab().save(str(out / "sweep.png"))
            written.append(out / "sweep.png")
        elif args.project:
            win.open_project(args.project, ask=False)
            settle(0.5)
            dialog = SweepDialog(win.doc, Path(tempfile.mkdtemp()) / "screenshot.sweep", win)
            key = "materials." + win.doc.material_names[0] + ".friction_angle_deg"
            dialog.params.cellWidget(0, 0).setCurrentText(key)
            dialog.params.cellWidget(0, 1).setCurrentText("uniform")
            dialog.params.item(0, 2).setText("20, 40")
            if "domain.boundaries.bottom.friction_angle_deg" in dialog.keys:  # a base as rough as the material
                dialog.params.item(0, 3).setText("domain.boundaries.bottom.friction_angle_deg")
            dialog.fixed.setText(args.fixed)
            dialog.runs.setValue(args.runs)
            dialog.thresholds.setText("0.02, 0.05")
            dialog.workers_box.setValue(2)
            dialog.show()
            settle(1.0)
            dialog.grab().save(str(out / "sweep_dialog.png"))
            written.append(out / "sweep_dialog.png")
            dialog.accept()
            if dialog.spec_path is None:
                print(dialog.error.text(), file=sys.stderr)
                return 1
            win.start_sweep(dialog.spec_path, dialog.out_dir, dialog.workers())
            t0 = time.perf_counter()
            while win.sweep_view.running and time.perf_counter() - t0 < args.timeout:
                settle(1.0)
            settle(2.0)
            win.grab().save(str(out / "sweep.png"))
            written.append(out / "sweep.png")
    finally:
        win.shutdown()
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    import os

    code = main()
    sys.stdout.flush()
    os._exit(code)  # see tests/conftest.py: windows with VTK views are not destroyed
