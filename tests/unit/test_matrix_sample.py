"""The suite's covering sample of the matrix tests (tests/conftest.py): what it keeps of a matrix."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from tests import conftest


class FakeItem:
    """Just enough of a pytest item for the sample: an id of hyphen-joined values, a file, a test."""

    def __init__(self, path: str, name: str, case_id: str, sample: int | None = None, known_limit=False):
        self.known_limit = known_limit
        self.path = path
        self.originalname = name
        self.callspec = SimpleNamespace(id=case_id, params={"scheme": None, "precision": None, "side": None})
        self._marker = SimpleNamespace(kwargs={} if sample is None else {"sample": sample})

    def get_closest_marker(self, name):
        if name == "xfail":
            return SimpleNamespace(kwargs={"strict": True}) if self.known_limit else None
        return self._marker if name == "matrix" else None


def _cases(path, name, sample=None):
    return [FakeItem(path, name, f"{s}-{p}-{side}", sample) for s in ("mpm", "apic", "apic-affine")
            for p in ("f32", "f64") for side in ("left", "bottom")]


def _select(items, monkeypatch, full=False):
    monkeypatch.setenv(conftest.FULL_MATRIX, "1" if full else "0")
    deselected = []
    config = SimpleNamespace(hook=SimpleNamespace(pytest_deselected=lambda items: deselected.extend(items)))
    kept = list(items)
    conftest.pytest_collection_modifyitems(config, kept)
    assert len(kept) + len(deselected) == len(items)
    return kept


def test_a_case_id_names_its_values_with_a_scheme_as_one_word():
    assert conftest.case_words(FakeItem("f", "t", "apic-affine-f32-left")) == {"apic_affine", "f32", "left"}


def test_the_sample_holds_most_values_first_and_is_cut_at_its_limit():
    items = [FakeItem("f", "t", i) for i in ("mpm-f32-left", "mpm-f32-bottom", "apic-f64-bottom")]
    assert [i.callspec.id for i in conftest.covering_sample(items, 1)] == ["mpm-f32-left"]
    assert [i.callspec.id for i in conftest.covering_sample(items, 2)] == ["mpm-f32-left", "apic-f64-bottom"]
    # values the file's earlier samples hold come last
    assert [i.callspec.id for i in conftest.covering_sample(items, 1, frozenset({"mpm", "f32", "left"}))] == [
        "apic-f64-bottom"]


@pytest.mark.parametrize("tests_in_file", [1, 2, 4])
def test_every_scheme_and_precision_of_a_file_runs_and_its_tests_share_out_the_rest(tests_in_file, monkeypatch):
    items = [i for t in range(tests_in_file) for i in _cases("file.py", f"test_{t}")]
    kept = _select(items, monkeypatch)
    words = set().union(*map(conftest.case_words, kept))
    assert {"mpm", "apic", "apic_affine", "f32", "f64"} <= words
    assert {"left", "bottom"} <= words
    assert all(any(i.originalname == f"test_{t}" for i in kept) for t in range(tests_in_file))  # every test runs
    assert len(kept) <= max(tests_in_file, 3)  # one case per test, plus what the schemes need


def test_a_marker_sample_and_the_full_matrix_are_kept(monkeypatch):
    items = _cases("file.py", "test_a", sample=4)
    kept = _select(items, monkeypatch)
    assert len(kept) <= 4  # a sample stops early once it holds every value
    assert set().union(*map(conftest.case_words, kept)) == set().union(*map(conftest.case_words, items))
    # mpm and apic cases, the default sample: one case, and one that brings apic and f64 (and bottom)
    two = _select(_cases("file.py", "test_b")[:8], monkeypatch)
    assert [i.callspec.id for i in two] == ["mpm-f32-left", "apic-f64-bottom"]
    assert len(_select(items, monkeypatch, full=True)) == len(items)


def test_the_files_are_sampled_apart(monkeypatch):
    items = _cases("a.py", "test_x") + _cases("b.py", "test_x")
    kept = _select(items, monkeypatch)
    for path in ("a.py", "b.py"):
        assert {"mpm", "apic", "apic_affine"} <= set().union(*(conftest.case_words(i) for i in kept if i.path == path))


def test_a_known_limit_is_sampled_only_where_a_test_has_nothing_else(monkeypatch):
    limit = FakeItem("f.py", "test_a", "mpm-f32-left-bottom", known_limit=True)  # the most values
    kept = _select([limit, FakeItem("f.py", "test_a", "mpm-f32-left")], monkeypatch)
    assert [i.callspec.id for i in kept] == ["mpm-f32-left"]
    only_limits = [limit, FakeItem("f.py", "test_b", "apic-f64-left", known_limit=True)]
    assert len(_select([limit], monkeypatch)) == 1
    assert {i.originalname for i in _select(only_limits, monkeypatch)} == {"test_a", "test_b"}
