"""Per-user state of the workbench: recent files, measured throughput, the material library.

Everything lives as JSON in the user's configuration folder (``RUNOUT_CONFIG_DIR`` when set, which
the tests use, else the platform's config location + ``/runout``), so it can be read, copied and
deleted by hand. A damaged file is logged and treated as empty: losing a recent-files list must
never stop the workbench from starting.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Any

from projects.atomic import write_atomic

logger = logging.getLogger(__name__)

SETTINGS_NAME = "workbench.json"
LIBRARY_NAME = "materials.json"
MAX_RECENT = 8
#: Particle-steps per second assumed before a run on this machine measured it: whole runs of
#: apic-affine on two CPU cores make 3.2e6 (3,200 particles) to 6.8e6 (20,000 particles) with
#: set-up and compilation included (docs/validation); the paper's GPU run made 7.6e7 on an RTX 3060.
ASSUMED_THROUGHPUT = {"cpu": 3.0e6, "gpu": 2.0e7}
#: The completed runs whose step times the estimate scales the cost model by (the latest ones).
STEP_TIMES_KEPT = 20


def config_dir() -> Path:
    """The folder of the workbench's JSON files (created on first write)."""
    env = os.environ.get("RUNOUT_CONFIG_DIR")
    if env:
        return Path(env)
    from PySide6.QtCore import QStandardPaths

    base = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.GenericConfigLocation)
    return Path(base or Path.home() / ".config") / "runout"


def _read_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        logger.warning("ignoring %s: %s", path, err)
        return {}
    return data if isinstance(data, dict) else {}


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


class Settings:
    """Recent projects and results, last folders and the measured throughput per device.

    Parameters
    ----------
    folder : Path, optional
        Where ``workbench.json`` lives (default :func:`config_dir`).
    """

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = Path(folder) if folder is not None else config_dir()
        self.path = self.folder / SETTINGS_NAME
        self._data = _read_json(self.path)

    def _save(self) -> None:
        try:
            _write_json(self.path, self._data)
        except OSError as err:
            logger.warning("could not save %s: %s", self.path, err)

    # -- recent files ---------------------------------------------------------------------

    def recent(self, kind: str = "projects") -> list[str]:
        """Recently opened paths of ``kind`` ("projects" or "results"), newest first, existing only."""
        items = self._data.get(f"recent_{kind}", [])
        return [p for p in items if isinstance(p, str) and Path(p).exists()][:MAX_RECENT]

    def add_recent(self, path: str | os.PathLike[str], kind: str = "projects") -> None:
        text = str(Path(path).absolute())
        items = [p for p in self._data.get(f"recent_{kind}", []) if p != text]
        self._data[f"recent_{kind}"] = [text, *items][:MAX_RECENT]
        self._save()

    # -- plain values ---------------------------------------------------------------------

    def get(self, key: str, default: Any = None) -> Any:
        return self._data.get(key, default)

    def set(self, key: str, value: Any) -> None:
        self._data[key] = value
        self._save()

    # -- throughput -------------------------------------------------------------------------

    def throughput(self, arch: str) -> tuple[float, bool]:
        """Particle-steps per second on ``arch`` ("cpu" or "gpu") and whether it was measured here."""
        measured = self._data.get("throughput", {}).get(arch)
        if isinstance(measured, (int, float)) and measured > 0:
            return float(measured), True
        return ASSUMED_THROUGHPUT.get(arch, ASSUMED_THROUGHPUT["cpu"]), False

    def record_step_time(self, arch: str, particles: int, step_time_s: float, structures: bool) -> None:
        """Remember a completed run's step time (``summary.json`` ``step_time_s``) at its size: the
        estimates of later runs on ``arch`` scale the shipped cost model to this machine by them."""
        if step_time_s > 0 and particles > 0 and arch in ("cpu", "gpu"):
            table = dict(self._data.get("step_times", {}))
            runs = [r for r in table.get(arch, []) if isinstance(r, list) and len(r) == 3][-(STEP_TIMES_KEPT - 1):]
            table[arch] = [*runs, [int(particles), float(step_time_s), bool(structures)]]
            self._data["step_times"] = table
            self._save()

    def step_cost(self, arch: str) -> Any:
        """The cost model of ``arch`` scaled to this machine by its measured runs
        (:func:`projects.cost.machine_step_cost`), or the shipped one (:data:`projects.cost.STEP_COSTS`)
        before the first; and how many runs it rests on."""
        from projects.cost import STEP_COSTS, machine_step_cost

        base = STEP_COSTS.get(arch, STEP_COSTS["cpu"])
        runs = [r for r in self._data.get("step_times", {}).get(arch, []) if isinstance(r, list) and len(r) == 3]
        if not runs:
            return base, 0
        source = f"measured on this machine ({len(runs)} run{'s' if len(runs) != 1 else ''})"
        return machine_step_cost([tuple(r) for r in runs], base, source), len(runs)

    def record_throughput(self, arch: str, particle_steps_per_s: float) -> None:
        """Remember the throughput of a completed run (the estimate of the next run uses it)."""
        if particle_steps_per_s > 0 and arch in ("cpu", "gpu"):
            table = dict(self._data.get("throughput", {}))
            table[arch] = float(particle_steps_per_s)
            self._data["throughput"] = table
            self._save()


class MaterialLibrary:
    """Named materials saved for reuse across projects (``materials.json``).

    Entries are material tables exactly as in a project file (``model``, ``density_kg_m3``,
    ...), so they validate with the project schema when inserted.
    """

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = Path(folder) if folder is not None else config_dir()
        self.path = self.folder / LIBRARY_NAME
        raw = _read_json(self.path).get("materials", {})
        self._items: dict[str, dict[str, Any]] = {
            k: dict(v) for k, v in raw.items() if isinstance(k, str) and isinstance(v, dict)
        }

    def names(self) -> list[str]:
        return sorted(self._items)

    def get(self, name: str) -> dict[str, Any]:
        return dict(self._items[name])

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def put(self, name: str, material: dict[str, Any]) -> None:
        """Add or replace ``name`` and write the file."""
        self._items[name] = dict(material)
        _write_json(self.path, {"materials": self._items})

    def remove(self, name: str) -> None:
        self._items.pop(name, None)
        _write_json(self.path, {"materials": self._items})
