"""Fixtures of the workbench tests: a window with its own config folder, answering no dialogs,
checked for leaked threads and VTK plotters when it closes and then kept, not deleted (see
tests/conftest.py); project files made from the tiny example (CPU)."""

from __future__ import annotations

import gc
import os
import threading
import time
from pathlib import Path

import pytest

from tests.conftest import KEPT_WIDGETS

os.environ.setdefault("QT_API", "pyside6")

EXAMPLES = Path(__file__).resolve().parents[2] / "projects" / "examples"
TINY = EXAMPLES / "tiny_column.toml"


@pytest.fixture(scope="session", autouse=True)
def _display():
    """Skip (rather than abort in Qt) where there is no display: pytest-xvfb provides one when
    the Xvfb binary is installed (Debian package ``xvfb``)."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        pytest.skip("no display: install Xvfb (apt-get install xvfb) so that pytest-xvfb can start one")


def _project_file(tmp_path: Path, name: str, overrides: list[str]) -> Path:
    from projects.document import apply_overrides, load_project, save_project

    if not TINY.is_file():
        pytest.skip("projects/examples/tiny_column.toml is not there")
    project = apply_overrides(load_project(TINY), ["numerics.arch=cpu", *overrides])
    path = tmp_path / name
    save_project(project, path)
    return path


@pytest.fixture
def tiny_file(tmp_path: Path) -> Path:
    """The tiny example on the CPU, as a file of its own (0.05 s, 250 steps)."""
    return _project_file(tmp_path, "tiny.toml", [])


@pytest.fixture
def long_file(tmp_path: Path) -> Path:
    """The tiny scene running for 20 s of simulated time: long enough to cancel or measure."""
    return _project_file(tmp_path, "long.toml", ["stages.1.duration_s=20.0", "output.interval_s=0.005"])


class UnexpectedDialog(AssertionError):
    pass


def _no_dialog(name: str):
    def ask(*_args, **_kwargs):
        raise UnexpectedDialog(f"the workbench asked {name}() and the test gave no answer")

    return ask


def _alive_plotters() -> int:
    from pyvista.plotting import plotter

    return len(plotter._ALL_PLOTTERS)


@pytest.fixture
def window(qtbot, tmp_path: Path, monkeypatch):
    """A shown MainWindow; questions to the user fail the test unless the test answers them."""
    from app.gui import configure_environment

    configure_environment()
    monkeypatch.setenv("RUNOUT_CONFIG_DIR", str(tmp_path / "config"))
    from app.gui.main_window import MainWindow
    from app.gui.settings import MaterialLibrary, Settings

    threads_before = threading.active_count()
    plotters_before = _alive_plotters()
    config = tmp_path / "config"
    win = MainWindow(settings=Settings(config), library=MaterialLibrary(config))
    for name in ("ask_save_changes", "ask_open_path", "ask_save_path", "ask_results_path", "ask_stop_run",
                 "ask_save_invalid", "show_error", "show_project_problems"):
        monkeypatch.setattr(win, name, _no_dialog(name))
    win.resize(1400, 850)
    win.show()
    qtbot.waitExposed(win)
    yield win
    win.shutdown()
    win.close()
    KEPT_WIDGETS.append(win)  # not deleted: see tests/conftest.py
    gc.collect()
    # the kept windows live to the end of the session: out of every later collection's way
    # (otherwise each collection walks all the windows kept so far, teardowns slowing test by test)
    gc.freeze()
    deadline = time.monotonic() + 5.0
    while threading.active_count() > threads_before and time.monotonic() < deadline:
        time.sleep(0.02)
    assert threading.active_count() == threads_before, [t.name for t in threading.enumerate()]
    assert _alive_plotters() == plotters_before, "a VTK plotter was not closed"

