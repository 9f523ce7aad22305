"""Inspectable artefacts of the 20-step method: one :class:`Step` per step, printable as
LaTeX or Markdown."""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


@dataclass(frozen=True)
class Step:
    """One step of the 20-step method (thesis §3.2, Figs. 3.3–3.7).

    Attributes
    ----------
    number : int
        Step number as in the thesis list (§3.2.2–3.2.5).
    title : str
    thesis : str
        Where the step is in the thesis (figure/equation numbers).
    items : dict
        Named artefacts: sympy expressions/matrices, tables (str) or tuples of names.
    note : str
        What the step does, in words.
    """

    number: int
    title: str
    thesis: str
    items: dict = field(default_factory=dict)
    note: str = ""

    def __getitem__(self, key):
        return self.items[key]

    def to_latex(self, symbol_names=None) -> str:
        out = [f"\\paragraph{{Step {self.number}: {self.title}}} ({self.thesis}) {self.note}", "\\begin{align*}"]
        text = []
        for name, obj in self.items.items():
            if isinstance(obj, (sp.Basic, sp.MatrixBase)):
                out.append(f"{_latex_name(name)} &= {sp.latex(obj, symbol_names=symbol_names)} \\\\")
            else:
                text.append(f"{name}: {obj}")
        out.append("\\end{align*}")
        if text:
            out.extend(text)
        return "\n".join(out)

    def to_markdown(self, symbol_names=None) -> str:
        out = [f"### Step {self.number}: {self.title}", f"*{self.thesis}.* {self.note}", ""]
        for name, obj in self.items.items():
            if isinstance(obj, (sp.Basic, sp.MatrixBase)):
                out.append(f"- {name}: $${sp.latex(obj, symbol_names=symbol_names)}$$")
            elif "\n" in str(obj):
                out.append(f"- {name}:\n\n{obj}\n")
            else:
                out.append(f"- {name}: {obj}")
        return "\n".join(out) + "\n"


def _latex_name(name: str) -> str:
    return "\\text{" + name.replace("_", "\\_") + "}"


class Steps(tuple):
    """The ordered steps; index by number with :meth:`get`."""

    def get(self, number: int) -> Step:
        for s in self:
            if s.number == number:
                return s
        raise KeyError(number)

    def to_markdown(self, symbol_names=None) -> str:
        return "\n".join(s.to_markdown(symbol_names) for s in self)

    def to_latex(self, symbol_names=None) -> str:
        return "\n\n".join(s.to_latex(symbol_names) for s in self)
