"""Editors bound to one key of the project: they show it, check what is typed, and commit edits.

Each editor knows its dotted key path. As the user types, the text is checked with the project
schema's own rule for that key (:func:`app.gui.document.check_value`), so the message is the one
``runout validate`` would print; a bad value is shown in red with the message as tooltip and in
the panel's message line, and is never written to the project. A value the schema accepts is
committed as one undo step when editing finishes. Number fields accept a unit after the number
("5 kPa", "20 kN/m3" for a unit weight into a density; see :mod:`app.gui.units`), store SI and
show the value again in the unit last typed for that key (``20 kN/m3``, the SI value in the
tooltip); a plain number brings back the SI unit.
A field left red blocks Run (:meth:`app.gui.main_window.MainWindow.invalid_fields`). Problems that involve several keys (found by
validating the whole project) are shown in orange on the editor of the key they name.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

from PySide6.QtCore import QEvent, QObject, Qt, Signal
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QSizePolicy,
    QSpinBox,
    QWidget,
)

from app.gui.document import ProjectDocument, check_value, format_number, parse_number, typed_or_kept
from app.gui.units import parse_quantity

logger = logging.getLogger(__name__)

ERROR_STYLE = "QLineEdit { background: #fde2e1; border: 1px solid #d93025; }"
PROBLEM_STYLE = "QLineEdit { background: #fff1d6; border: 1px solid #e37400; }"


def unit_label(unit: str) -> QLabel:
    """A fixed-width label for a unit, so that fields line up in a form."""
    label = QLabel(unit)
    label.setMinimumWidth(38)
    label.setSizePolicy(QSizePolicy.Policy.Fixed, QSizePolicy.Policy.Preferred)
    label.setStyleSheet("color: #555;")
    return label


def forget_typing(edit: QLineEdit) -> None:
    """The text of ``edit`` is the project's now (committed as an undo step, or equal to the
    value): clear the field's own undo history, so that Ctrl+Z there undoes the project's step
    (:class:`TypingUndo`) instead of putting the old text back in the field alone, which the
    project did not follow (and leaving the field then committed it as one more step)."""
    if edit.isUndoAvailable() or edit.isRedoAvailable():
        pos = edit.cursorPosition()
        edit.setText(edit.text())  # clears the history; emits textChanged, not textEdited
        edit.setCursorPosition(pos)


class TypingUndo(QObject):
    """Event filter of the text fields of a window with a project-level Undo: Ctrl+Z (and Redo)
    in a field undoes its own typing, what it holds that the project does not (Qt's undo of the
    field), and only that; a field with nothing of its own to undo passes the key on to the
    window's Undo action instead of swallowing it, as a QLineEdit does."""

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt's name
        if event.type() not in (QEvent.Type.ShortcutOverride, QEvent.Type.KeyPress):
            return False
        # a spin box takes the key for its line edit
        edit = obj if isinstance(obj, QLineEdit) else obj.findChild(QLineEdit) if isinstance(
            obj, QAbstractSpinBox) else None
        if edit is None or edit.isReadOnly():
            return False
        if event.matches(QKeySequence.StandardKey.Undo):
            own = edit.isUndoAvailable()
        elif event.matches(QKeySequence.StandardKey.Redo):
            own = edit.isRedoAvailable()
        else:
            return False
        if own:
            return False
        # the override left unaccepted, the window's action takes the key; a key press that no
        # action took (nothing to undo in the project either) does nothing
        event.ignore()
        return True


class _Bound(QWidget):
    """Base of editors bound to a key path of a document.

    Signals
    -------
    message(str)
        What is wrong with the typed value ("" when nothing is).
    """

    message = Signal(str)

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc = doc
        self.path = path
        self.label = label
        doc.changed.connect(self._on_doc_changed)

    def set_path(self, path: str | None) -> None:
        """Bind to another key (the panel's current material or stage changed)."""
        self.path = path
        self.setEnabled(path is not None)
        self.refresh()

    def _on_doc_changed(self, _sections: object) -> None:
        self.refresh()

    def refresh(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def value(self) -> Any:
        return self.doc.get(self.path) if self.path else None

    def _problem_text(self) -> str:
        if not self.path:
            return ""
        return "\n".join(p.message for p in self.doc.problems if p.path == self.path)


class NumberField(_Bound):
    """A number with its unit; empty text means "left out" when ``optional``."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, unit: str, *,
                 optional: bool = False, placeholder: str = "", integer: bool = False,
                 words: Sequence[str] = (), parent: QWidget | None = None) -> None:
        super().__init__(doc, path, label, parent)
        self.optional = optional
        self.integer = integer  # a count (max_trials): written as an integer
        self.words = tuple(words)  # words the key takes instead of a number ("limit-equilibrium")
        self.edit = QLineEdit()
        self.edit.setPlaceholderText(placeholder or ("none" if optional else ""))
        self.edit.setAlignment(Qt.AlignmentFlag.AlignRight)
        self.edit.setAccessibleName(label)
        self.unit = unit_label(unit)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.edit, 1)
        layout.addWidget(self.unit)
        self.edit.textEdited.connect(self._check)
        self.edit.editingFinished.connect(self.commit)
        self.error = ""
        #: per key, the unit last typed with a value there ("20 kN/m3" into a density): the field
        #: shows the value in it again, not converted to the SI unit it stores
        self.shown_units: dict[str, str] = {}
        self.refresh()

    def _factor(self, unit: str) -> float | None:
        """SI per one ``unit`` typed in this field (None: not a unit it converts)."""
        value, error = parse_quantity(f"1 {unit}", self.unit.text())
        return None if error or value is None or not value > 0 else value

    def shown_text(self, value: Any) -> str:
        """``value`` (SI) as the field shows it: in the unit last typed for this key, else SI."""
        unit = self.shown_units.get(self.path or "")
        factor = self._factor(unit) if unit else None
        if isinstance(value, (int, float)) and not isinstance(value, bool) and factor is not None:
            return f"{format_number(float(value) / factor)} {unit}"
        return format_number(value) if value is not None else ""

    def _remember_unit(self, text: str) -> None:
        from app.gui.units import split_unit

        if not self.path:
            return
        _number, unit = split_unit(text)
        if unit and self.unit.text() != "°" and self._factor(unit) not in (None, 1.0):
            self.shown_units[self.path] = unit
        else:
            self.shown_units.pop(self.path, None)

    def _parse(self, text: str) -> tuple[Any, str]:
        if not text.strip():
            return None, "" if self.optional else "required"
        if text.strip() in self.words:
            return text.strip(), check_value(self.path, text.strip()) or "" if self.path else ""
        number, error = parse_quantity(text, self.unit.text())  # "5 kPa" -> 5000.0 in a Pa field
        if number is None:
            return None, error
        if self.integer:
            if not float(number).is_integer():
                return None, "must be an integer"
            number = int(number)
        if self.path is None:
            return number, ""
        return number, check_value(self.path, number) or ""

    def _check(self, text: str) -> None:
        _, self.error = self._parse(text)
        self._style()
        self.message.emit(f"{self.label}: {self.error}" if self.error else "")

    def _style(self) -> None:
        problem = self._problem_text()
        if self.error:
            self.edit.setStyleSheet(ERROR_STYLE)
            self.edit.setToolTip(self.error)
        elif problem:
            self.edit.setStyleSheet(PROBLEM_STYLE)
            self.edit.setToolTip(problem)
        else:
            self.edit.setStyleSheet("")
            value = self.value()
            shown = self.path in self.shown_units and isinstance(value, (int, float))
            self.edit.setToolTip(f"stored as {format_number(value)} {self.unit.text()}" if shown else "")

    def commit(self) -> bool:
        """Write the typed value to the project (one undo step) if the schema accepts it."""
        if self.path is None:
            return False
        value, self.error = self._parse(self.edit.text())
        self._style()
        if self.error:
            self.message.emit(f"{self.label}: {self.error}")
            return False
        current = self.value()
        text = self.edit.text()
        value = current if current is not None and text.strip() == self.shown_text(current) else \
            typed_or_kept(text, value, current)
        self._remember_unit(text)
        changed = not (value == current and (value is None) == (current is None))
        done = changed and self.doc.set_value(self.path, value, f"change {self.label.lower()}")
        if not done:
            self.refresh()  # the value in the unit just typed
        forget_typing(self.edit)
        return done

    def set_text(self, text: str) -> None:
        """Type ``text`` and finish editing (what a user does; used by scripts and tests)."""
        self.edit.setText(text)
        self._check(text)
        self.commit()

    def refresh(self) -> None:
        if self.error and self.edit.hasFocus():
            return  # keep what the user is typing
        value = self.value()
        text = self.shown_text(value)
        if self.edit.text() != text:
            self.edit.setText(text)
        self.error = ""
        self._style()


class PairField(_Bound):
    """An ``[x, y]`` pair: two numbers sharing one unit."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, unit: str,
                 names: tuple[str, str] = ("x", "y"), parent: QWidget | None = None) -> None:
        super().__init__(doc, path, label, parent)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.edits: list[QLineEdit] = []
        for name in names:
            edit = QLineEdit()
            edit.setAlignment(Qt.AlignmentFlag.AlignRight)
            edit.setPlaceholderText(name)
            edit.setToolTip(name)
            edit.setAccessibleName(f"{label} {name}")
            edit.textEdited.connect(self._check)
            edit.editingFinished.connect(self.commit)
            layout.addWidget(QLabel(name))
            layout.addWidget(edit, 1)
            self.edits.append(edit)
        layout.addWidget(unit_label(unit))
        self.error = ""
        self.refresh()

    def _parse(self) -> tuple[list[float] | None, str]:
        numbers = [parse_number(e.text()) for e in self.edits]
        if any(n is None for n in numbers):
            return None, "both components must be numbers"
        pair = [float(n) for n in numbers]  # type: ignore[arg-type]
        return pair, (check_value(self.path, pair) or "") if self.path else ""

    def _check(self, _text: str = "") -> None:
        _, self.error = self._parse()
        self._style()
        self.message.emit(f"{self.label}: {self.error}" if self.error else "")

    def _style(self) -> None:
        problem = self._problem_text()
        style = ERROR_STYLE if self.error else PROBLEM_STYLE if problem else ""
        for edit in self.edits:
            edit.setStyleSheet(style)
            edit.setToolTip(self.error or problem)

    def commit(self) -> bool:
        if self.path is None:
            return False
        value, self.error = self._parse()
        self._style()
        if self.error or value is None:
            return False
        current = self.value()
        if isinstance(current, (list, tuple)) and len(current) == 2:
            value = [typed_or_kept(edit.text(), v, c) for edit, v, c in zip(self.edits, value, current, strict=True)]
        done = value != current and self.doc.set_value(self.path, value, f"change {self.label.lower()}")
        for edit in self.edits:
            forget_typing(edit)
        return done

    def set_values(self, x: float, y: float) -> None:
        self.edits[0].setText(format_number(x))
        self.edits[1].setText(format_number(y))
        self._check()
        self.commit()

    def refresh(self) -> None:
        if self.error and any(e.hasFocus() for e in self.edits):
            return
        value = self.value()
        if isinstance(value, (list, tuple)) and len(value) == 2:
            for edit, v in zip(self.edits, value, strict=True):
                text = format_number(v)
                if edit.text() != text:
                    edit.setText(text)
        else:
            for edit in self.edits:
                edit.setText("")
        self.error = ""
        self._style()


class ChoiceField(_Bound):
    """One of a fixed set of strings (scheme, precision, model, ...)."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, choices: Sequence[str],
                 default: str | None = None, parent: QWidget | None = None) -> None:
        super().__init__(doc, path, label, parent)
        self.default = default
        self.combo = QComboBox()
        self.combo.addItems(list(choices))
        self.combo.setAccessibleName(label)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.combo, 1)
        self.combo.activated.connect(self._chosen)
        self.refresh()

    def _chosen(self, _index: int) -> None:
        if self.path is None:
            return
        choice = self.combo.currentText()
        if choice != self.value():
            self.doc.set_value(self.path, choice, f"change {self.label.lower()}")

    def choose(self, text: str) -> None:
        """Pick ``text`` as a user would."""
        self.combo.setCurrentText(text)
        self._chosen(self.combo.currentIndex())

    def refresh(self) -> None:
        value = self.value()
        if value is None:
            value = self.default
        self.combo.blockSignals(True)
        index = self.combo.findText(str(value)) if value is not None else -1
        self.combo.setCurrentIndex(index)
        self.combo.blockSignals(False)


class OptionalChoiceField(ChoiceField):
    """One of a fixed set of strings, or none: the first entry, ``none_text``, leaves the key out
    (``on_none`` is called instead where leaving it out takes more, the keys that go with it)."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, choices: Sequence[str],
                 none_text: str = "none", on_none: Callable[[], Any] | None = None,
                 parent: QWidget | None = None) -> None:
        self.none_text = none_text
        self.on_none = on_none
        super().__init__(doc, path, label, (none_text, *choices), default=none_text, parent=parent)

    def _chosen(self, index: int) -> None:
        if self.path is None:
            return
        if self.combo.currentText() != self.none_text:
            super()._chosen(index)
        elif self.value() is not None:
            if self.on_none is not None:
                self.on_none()
            else:
                self.doc.set_value(self.path, None, f"remove {self.label.lower()}")


class IntField(_Bound):
    """A bounded integer (particles per cell)."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, lo: int, hi: int,
                 default: int, suffix: str = "", parent: QWidget | None = None) -> None:
        super().__init__(doc, path, label, parent)
        self.default = default
        self.spin = QSpinBox()
        self.spin.setRange(lo, hi)
        self.spin.setSuffix(suffix)
        self.spin.setAccessibleName(label)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.spin, 1)
        self.spin.editingFinished.connect(self._commit)
        self.spin.valueChanged.connect(self._stepped)
        self.refresh()

    def _stepped(self, _value: int) -> None:
        # arrow clicks finish an edit at once; typed digits wait for editingFinished
        if not self.spin.lineEdit().hasFocus():
            self._commit()

    def _commit(self) -> None:
        if self.path is not None and self.spin.value() != self.value():
            self.doc.set_value(self.path, int(self.spin.value()), f"change {self.label.lower()}")
        edit = self.spin.findChild(QLineEdit)
        if self.path is not None and edit is not None:
            self.spin.blockSignals(True)  # the same text again: no valueChanged
            forget_typing(edit)
            self.spin.blockSignals(False)

    def refresh(self) -> None:
        value = self.value()
        self.spin.blockSignals(True)
        self.spin.setValue(int(value) if isinstance(value, int) else self.default)
        self.spin.blockSignals(False)


class TextField(_Bound):
    """A string key (title, body and stage names); empty text removes an optional key."""

    def __init__(self, doc: ProjectDocument, path: str | None, label: str, *, optional: bool = False,
                 taken: Callable[[], dict[str, str]] | None = None, parent: QWidget | None = None) -> None:
        super().__init__(doc, path, label, parent)
        self.optional = optional
        # names that must not be given (name -> what has it): a duplicate is refused where it is
        # typed, not reported later against the other item that had the name first
        self.taken = taken
        self.edit = QLineEdit()
        self.edit.setAccessibleName(label)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.edit, 1)
        self.edit.editingFinished.connect(self.commit)
        self.edit.textEdited.connect(self._check)
        self.error = ""
        self.refresh()

    def _check(self, text: str) -> None:
        value: Any = text if text.strip() or not self.optional else None
        self.error = (check_value(self.path, value) or "") if self.path else ""
        owner = self.taken().get(value) if self.path and not self.error and self.taken and value != self.value() else None
        if owner:
            self.error = f"{owner} is already named {value!r}; names must be unique"
        self.edit.setStyleSheet(ERROR_STYLE if self.error else "")
        self.edit.setToolTip(self.error)
        self.message.emit(f"{self.label}: {self.error}" if self.error else "")

    def commit(self) -> bool:
        if self.path is None:
            return False
        text = self.edit.text()
        self._check(text)
        if self.error:
            return False
        value: Any = text if text.strip() or not self.optional else None
        done = value != self.value() and self.doc.set_value(self.path, value, f"change {self.label.lower()}")
        forget_typing(self.edit)
        return done

    def set_text(self, text: str) -> None:
        self.edit.setText(text)
        self.commit()

    def refresh(self) -> None:
        if self.error and self.edit.hasFocus():
            return
        value = self.value()
        text = "" if value is None else str(value)
        if self.edit.text() != text:
            self.edit.setText(text)
        problem = self._problem_text()
        self.error = ""
        self.edit.setStyleSheet(PROBLEM_STYLE if problem else "")
        self.edit.setToolTip(problem)
