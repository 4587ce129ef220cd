"""Rigid bodies in the workbench's material form: the biaxial example's platen shows its velocity
and contact in their own group and no stiffness; a velocity typed is saved; a material made rigid
loses its soil keys (and gets them back when made deformable again), and the file it saves is a
valid project."""

from __future__ import annotations

import shutil
import tomllib

import pytest

from projects.document import load_project
from tests.gui.conftest import EXAMPLES

pytestmark = pytest.mark.gui

BIAXIAL = EXAMPLES / "biaxial_softening_clay.toml"


@pytest.fixture
def biaxial_file(tmp_path):
    path = tmp_path / "biaxial.toml"
    shutil.copyfile(BIAXIAL, path)
    return path


def _materials(path):
    with open(path, "rb") as f:
        return tomllib.load(f)["materials"]


def test_the_platen_shows_its_velocity_and_contact_and_no_stiffness(window, biaxial_file, tmp_path):
    assert window.open_project(biaxial_file)
    panel = window.materials_panel
    panel.select("platen")
    assert panel.rigid_box.isVisibleTo(panel)
    assert [e.text() for e in panel.velocity.edits] == ["0", "-0.05"]
    assert panel.contact.combo.currentText() == "fixed"
    assert panel.fields["density_kg_m3"].path == "materials.platen.density_kg_m3"
    for key in ("youngs_modulus_pa", "poisson_ratio", "cohesion_pa", "damping_ratio"):
        assert panel.fields[key].path is None, key
        assert not panel.fields[key].isVisibleTo(panel), key  # no empty soil rows above its own group
    assert panel.fields["density_kg_m3"].isVisibleTo(panel) and not panel.inertial_box.isVisibleTo(panel)
    panel.velocity.edits[1].setText("-0.02")
    assert panel.velocity.commit()
    panel.contact.choose("slip")
    out = tmp_path / "saved.toml"
    window.doc.save(out)
    platen = _materials(out)["platen"]
    assert platen["velocity_m_s"] == [0.0, -0.02] and platen["contact"] in ("slip", {"type": "slip"})
    load_project(out)  # a valid project
    panel.select("clay")
    assert not panel.rigid_box.isVisibleTo(panel)
    assert panel.fields["youngs_modulus_pa"].path == "materials.clay.youngs_modulus_pa"
    assert panel.fields["youngs_modulus_pa"].isVisibleTo(panel) and panel.inertial_box.isVisibleTo(panel)


def test_a_material_made_rigid_and_back_keeps_a_valid_project(window, biaxial_file, tmp_path):
    assert window.open_project(biaxial_file)
    panel = window.materials_panel
    panel.select("weak_patch")
    panel.set_model("rigid")
    out = tmp_path / "rigid.toml"
    window.doc.save(out)
    patch = _materials(out)["weak_patch"]
    assert set(patch) == {"model", "density_kg_m3", "velocity_m_s", "contact"}
    load_project(out)
    panel.set_model("linear-elastic")
    window.doc.save(out)
    patch = _materials(out)["weak_patch"]
    assert "velocity_m_s" not in patch and patch["youngs_modulus_pa"] > 0 and 0 <= patch["poisson_ratio"] < 0.5
    load_project(out)
