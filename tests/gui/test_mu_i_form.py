"""Rate-dependent friction in the workbench: the mu(I) law's four keys in their own group of the
material form, shown from the file (the aluminium-bar example), typed with units, saved and read
back unchanged; a value the schema refuses is red, named on the message line and not saved; a
linear-elastic material has no friction to make rate-dependent."""

from __future__ import annotations

import shutil
import tomllib

import pytest

from projects.document import load_project
from tests.gui.conftest import EXAMPLES

pytestmark = pytest.mark.gui

BUI = EXAMPLES / "bui2008_aluminium_bars.toml"
KEYS = ("mu_i_friction_increase", "mu_i_reference_number", "grain_diameter_m", "grain_density_kg_m3")


@pytest.fixture
def bui_file(tmp_path):
    if not BUI.is_file():
        pytest.skip("projects/examples/bui2008_aluminium_bars.toml is not there")
    path = tmp_path / "bui2008.toml"
    shutil.copyfile(BUI, path)
    return path


def _bars(path):
    with open(path, "rb") as f:
        return tomllib.load(f)["materials"]["bars"]


def test_the_example_shows_its_mu_i_values_and_saves_them_unchanged(window, bui_file, tmp_path):
    assert window.open_project(bui_file)
    panel = window.materials_panel
    panel.select("bars")
    assert panel.inertial_box.title() == "Rate-dependent friction (mu(I))"
    fields = {k: panel.fields[k] for k in KEYS}
    assert all(f.isEnabled() and f.path == f"materials.bars.{k}" for k, f in fields.items())
    assert fields["mu_i_friction_increase"].edit.text() == "0.26"
    assert fields["mu_i_reference_number"].edit.text() == "0.279"
    assert fields["grain_diameter_m"].edit.text() == "0.00125"
    assert fields["grain_diameter_m"].unit.text() == "m"
    assert fields["grain_density_kg_m3"].edit.text() == ""  # left out: the material's density
    assert fields["grain_density_kg_m3"].edit.placeholderText() == "= density"
    out = tmp_path / "saved.toml"
    window.doc.save(out)
    before, after = _bars(BUI), _bars(out)
    assert {k: after.get(k) for k in KEYS} == {k: before.get(k) for k in KEYS}
    assert "grain_density_kg_m3" not in after


def test_edit_a_mu_i_value_with_a_unit_save_and_read_back(window, bui_file, tmp_path):
    assert window.open_project(bui_file)
    doc, panel = window.doc, window.materials_panel
    panel.select("bars")
    panel.fields["grain_diameter_m"].set_text("1.5 mm")
    panel.fields["grain_density_kg_m3"].set_text("2.5 t/m3")
    panel.fields["mu_i_friction_increase"].set_text("0.3")
    assert doc.project is not None, doc.problems
    assert doc.get("materials.bars.grain_diameter_m") == pytest.approx(0.0015)
    out = tmp_path / "edited.toml"
    doc.save(out)
    bars = load_project(out).materials["bars"]
    assert bars.grain_diameter_m == pytest.approx(0.0015)
    assert bars.grain_density_kg_m3 == pytest.approx(2500.0)
    assert bars.mu_i_friction_increase == 0.3 and bars.mu_i_reference_number == 0.279
    assert window.open_project(out, ask=False)
    panel.select("bars")
    assert panel.fields["mu_i_friction_increase"].edit.text() == "0.3"
    assert panel.fields["grain_density_kg_m3"].edit.text() == "2.5 t/m3"  # in the unit last typed


def test_a_bad_mu_i_value_is_red_named_and_not_saved(window, bui_file, tmp_path):
    assert window.open_project(bui_file)
    doc, panel = window.doc, window.materials_panel
    panel.select("bars")
    field = panel.fields["mu_i_reference_number"]
    field.set_text("-0.1")
    assert field.error == "must be > 0"
    assert "#fde2e1" in field.edit.styleSheet() and field.edit.toolTip() == "must be > 0"
    assert panel.message.text() == "Reference inertial number I₀: must be > 0"
    assert doc.get("materials.bars.mu_i_reference_number") == 0.279
    assert any("mu_i_reference_number" in line for line in window.invalid_fields())
    bad = panel.fields["grain_diameter_m"]
    bad.set_text("1.5 kg")  # not a length
    assert bad.error and doc.get("materials.bars.grain_diameter_m") == 0.00125
    out = tmp_path / "refused.toml"
    doc.save(out)
    bars = _bars(out)
    assert bars["mu_i_reference_number"] == 0.279 and bars["grain_diameter_m"] == 0.00125


def test_a_friction_increase_alone_names_the_missing_keys_and_elastic_has_none(window, tiny_file):
    assert window.open_project(tiny_file)
    doc, panel = window.doc, window.materials_panel
    panel.select("sand")
    assert all(panel.fields[k].isEnabled() and panel.fields[k].edit.text() == "" for k in KEYS)
    panel.fields["mu_i_friction_increase"].set_text("0.26")
    assert doc.project is None
    missing = {p.path for p in doc.problems}
    assert {"materials.sand.mu_i_reference_number", "materials.sand.grain_diameter_m"} <= missing
    panel.fields["mu_i_reference_number"].set_text("0.279")
    panel.fields["grain_diameter_m"].set_text("2 mm")
    assert doc.project is not None, doc.problems
    panel.set_model("linear-elastic")
    assert not any(k in doc.get("materials.sand") for k in KEYS)
    assert not any(panel.fields[k].path for k in KEYS) and doc.project is not None
