"""Inspectable artefacts of the 20-step method: one :class:`Step` per step, printable as
LaTeX or Markdown within a time/size budget.

Artefacts are addressed by stable identifiers (``model.steps[5].A``, ``model.steps[17].J``);
the display label of each is kept separately (``step.labels``). Large expressions are printed
with common subexpressions pulled out (``sympy.cse``) instead of being simplified; the LaTeX
output is plain ASCII (Unicode of the notes is transliterated to LaTeX macros) and compiles
with a standard LaTeX engine (``\\usepackage{amsmath}``).
"""
from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass, field
from typing import NamedTuple

import sympy as sp

#: expressions with more operations than this are printed with common subexpressions
DISPLAY_OPS = 400

_UNICODE_TEX = {
    "ω": r"\omega", "ξ": r"\xi", "Ω": r"\Omega", "μ": r"\mu", "Γ": r"\Gamma", "τ": r"\tau",
    "∂": r"\partial", "∇": r"\nabla", "θ": r"\theta", "φ": r"\phi", "ψ": r"\psi", "λ": r"\lambda",
    "⁻¹": "^{-1}", "ᵀ": "^{T}", "²": "^{2}", "≠": r"\neq", "∩": r"\cap", "·": r"\cdot",
    "½": r"\tfrac{1}{2}", "→": r"\to", "≤": r"\leq", "Σ": r"\Sigma", "⟨": r"\langle", "⟩": r"\rangle",
    "ℝ": r"\mathbb{R}", "×": r"\times", "−": "-", "∈": r"\in", "⇔": r"\Leftrightarrow",
}
_COMBINING = {"\u0307": r"\dot", "\u0303": r"\tilde", "\u0304": r"\bar"}
_TEXT_PUNCT = {"–": "--", "—": "---", "…": r"\ldots{}", "’": "'", "“": "``", "”": "''"}


def tex_text(text: str) -> str:
    """Plain text with Unicode maths → LaTeX (ASCII only): symbols in ``$…$``, LaTeX specials
    escaped."""
    out = []
    chars = list(unicodedata.normalize("NFC", str(text)))
    i = 0
    while i < len(chars):
        ch = chars[i]
        nxt = chars[i + 1] if i + 1 < len(chars) else ""
        decomposed = unicodedata.normalize("NFD", ch)
        if len(decomposed) == 2 and decomposed[1] in _COMBINING:       # ṙ, ṡ, Ṗ (precomposed)
            out.append(f"${_COMBINING[decomposed[1]]}{{{_math_char(decomposed[0])}}}$")
        elif nxt in _COMBINING:                                            # q̇, P̃, M̄
            out.append(f"${_COMBINING[nxt]}{{{_math_char(ch)}}}$")
            i += 1
        elif ch + nxt in _UNICODE_TEX:
            out.append(f"${_UNICODE_TEX[ch + nxt]}$")
            i += 1
        elif ch in _UNICODE_TEX or _greek(ch):
            out.append(f"${_math_char(ch)}$")
        elif ch in _TEXT_PUNCT:
            out.append(_TEXT_PUNCT[ch])
        elif ch in "_#%&{}":
            out.append("\\" + ch)
        elif ch in "^~\\":
            out.append({"^": r"\^{}", "~": r"\~{}", "\\": r"\textbackslash{}"}[ch])
        elif ch in "<>|":
            out.append({"<": "$<$", ">": "$>$", "|": r"$\vert$"}[ch])
        elif ord(ch) < 128:
            out.append(ch)
        else:
            out.append(unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode() or "?")
        i += 1
    return re.sub(r"\$\$", "", "".join(out))      # join adjacent math runs


def _greek(ch):
    """\\alpha for α, \\Gamma for Γ (None for other characters)."""
    name = unicodedata.name(ch, "")
    for prefix, case in (("GREEK SMALL LETTER ", str.lower), ("GREEK CAPITAL LETTER ", str.capitalize)):
        if name.startswith(prefix):
            word = name[len(prefix):].replace("LAMDA", "LAMBDA")
            if " " not in word:
                return "\\" + case(word)
    return None


def _math_char(ch):
    return _UNICODE_TEX.get(ch) or _greek(ch) or ch


def default_symbol_names(symbols) -> dict:
    """LaTeX names: ``x_dot`` → \\dot{x}, ``pt_psi`` → \\tilde{p}_{\\psi}, ``Omega`` → \\Omega."""
    out = {}
    for s in symbols:
        name = s.name
        if name.endswith("_dot"):
            out[s] = f"\\dot{{{sp.latex(sp.Symbol(name[:-4]))}}}"
        elif name.startswith("pt_"):
            out[s] = f"\\tilde{{p}}_{{{sp.latex(sp.Symbol(name[3:]))}}}"
        elif name.startswith("p_"):
            out[s] = f"p_{{{sp.latex(sp.Symbol(name[2:]))}}}"
    return out


def _ops(obj) -> int:
    try:
        return int(sp.count_ops(obj)) if isinstance(obj, sp.Basic) else sum(int(sp.count_ops(e)) for e in obj)
    except Exception:  # noqa: BLE001 - display only; a failure means "large"
        return DISPLAY_OPS + 1


def _symbolic(obj) -> bool:
    return isinstance(obj, (sp.Basic, sp.MatrixBase))


def latex_of(obj, symbol_names=None) -> str:
    """LaTeX of an artefact: directly when small, else with common subexpressions x_i."""
    names = dict(symbol_names or {})
    if not _symbolic(obj):
        return r"\text{" + tex_text(str(obj)) + "}"
    if _ops(obj) <= DISPLAY_OPS:
        return sp.latex(obj, symbol_names=names)
    exprs = list(obj) if isinstance(obj, sp.MatrixBase) else [obj]
    reps, reduced = sp.cse(exprs, optimizations=None)
    body = sp.Matrix(obj.shape[0], obj.shape[1], reduced) if isinstance(obj, sp.MatrixBase) else reduced[0]
    where = r",\ ".join(f"{sp.latex(a)} = {sp.latex(b, symbol_names=names)}" for a, b in reps)
    return sp.latex(body, symbol_names=names) + (r" \quad\text{with } " + where if reps else "")


#: expressions with more tree nodes than this are not rearranged by :func:`readable` (a
#: system built from bodies has metric entries of thousands of nodes: they are printed with
#: common subexpressions, and rearranging them cost more than the rest of the derivation)
READABLE_NODES = 400


def readable(obj):
    """``obj`` (an expression or a matrix) in a form to read, computed once where a derivation
    stores what it shows (the displayed M(q) of step 1, the singular set), never at print time:
    the trig normal form (:func:`~nhgait.dynamics.algebra.trig.tidy`: m_s(sin²θ + cos²θ) → m_s),
    then collected in the trig monomials with each coefficient's common factors pulled out
    (−(a m + b m_s) sin θ − m_s s cos θ; ``factor_terms``, no polynomial factorisation, so it
    stays cheap). Expressions above :data:`READABLE_NODES` nodes keep the normal form."""
    from ..algebra.trig import has_trig, tidy, tree_size
    if isinstance(obj, sp.MatrixBase):
        return obj.applyfunc(readable)
    if (not isinstance(obj, sp.Expr) or obj.is_Atom or not has_trig(obj)     # no identity to apply
            or tree_size(obj, READABLE_NODES) > READABLE_NODES):
        return obj
    e = tidy(obj)
    if not isinstance(e, sp.Expr) or e.is_Atom or tree_size(e, READABLE_NODES) > READABLE_NODES:
        return e
    numerator, denominator = sp.fraction(e)
    monomials = sorted(numerator.atoms(sp.sin, sp.cos), key=sp.default_sort_key)
    if not monomials or not numerator.is_Add or len(numerator.args) < 3:
        return e
    groups = sp.collect(numerator, monomials, evaluate=False)
    return sp.Add(*[sp.factor_terms(c) * m for m, c in groups.items()]) / sp.factor_terms(denominator)


def text_of(obj) -> str:
    """Plain text of an artefact: ``sstr`` when small, else with common subexpressions."""
    if not _symbolic(obj):
        return str(obj)
    if _ops(obj) <= DISPLAY_OPS:
        return sp.sstr(obj)
    exprs = list(obj) if isinstance(obj, sp.MatrixBase) else [obj]
    reps, reduced = sp.cse(exprs, optimizations=None)
    body = sp.Matrix(obj.shape[0], obj.shape[1], reduced) if isinstance(obj, sp.MatrixBase) else reduced[0]
    return sp.sstr(body) + ("  where " + "; ".join(f"{a} = {sp.sstr(b)}" for a, b in reps) if reps else "")


class Stepped(NamedTuple):
    """What a step function that feeds later steps returns: its displayed ``step`` and the
    ``value`` the later steps use (``step, value = reconstruction(...)`` still unpacks)."""

    step: Step
    value: object


@dataclass(frozen=True)
class Step:
    """One step of the 20-step method (thesis §3.2, Figs. 3.3–3.7).

    Attributes
    ----------
    number : int
        Step number as in the thesis list (§3.2.2–3.2.5).
    title, thesis, note : str
        Name, where the step is in the thesis (figure/equation numbers), what it does.
    items : dict
        Artefacts by stable identifier (``step.A`` or ``step["A"]``): sympy expressions or
        matrices, tables or text; CasADi SX objects for the implicit form's later steps.
    labels : dict
        Display label of an identifier (defaults to the identifier).
    """

    number: int
    title: str
    thesis: str
    items: dict = field(default_factory=dict)
    note: str = ""
    labels: dict = field(default_factory=dict)

    def __getitem__(self, key):
        """An artefact by identifier, or by its display label."""
        if key in self.items:
            return self.items[key]
        for ident, label in self.labels.items():
            if label == key:
                return self.items[ident]
        raise KeyError(key)

    def __getattr__(self, name):
        if name.startswith("_") or name in ("items", "labels"):
            raise AttributeError(name)
        try:
            return self.items[name]
        except KeyError:
            raise AttributeError(f"step {self.number} has no artefact {name!r} "
                                 f"(artefacts: {', '.join(self.items)})") from None

    def label(self, key) -> str:
        return self.labels.get(key, key)

    def to_latex(self, symbol_names=None) -> str:
        head = (f"\\paragraph{{Step {self.number}: {tex_text(self.title)}}} ({tex_text(self.thesis)}) "
                f"{tex_text(self.note)}")
        maths, text = [], []
        for key, obj in self.items.items():
            name = r"\text{" + tex_text(self.label(key)) + "}"
            if _symbolic(obj):
                maths.append(f"{name} &= {latex_of(obj, symbol_names)} \\\\")
            else:
                text.append(f"\\par\\noindent {tex_text(self.label(key))}: {_text_block(obj)}")
        out = [head]
        if maths:
            out += ["\\begin{align*}", *maths, "\\end{align*}"]
        return "\n".join(out + text)

    def to_markdown(self, symbol_names=None) -> str:
        out = [f"### Step {self.number}: {self.title}", f"*{self.thesis}.* {self.note}", ""]
        for key, obj in self.items.items():
            if _symbolic(obj):
                out.append(f"- {self.label(key)}: $${latex_of(obj, symbol_names)}$$")
            elif "\n" in str(obj):
                out.append(f"- {self.label(key)}:\n\n{obj}\n")
            else:
                out.append(f"- {self.label(key)}: {obj}")
        return "\n".join(out) + "\n"


def _text_block(obj) -> str:
    lines = str(obj).splitlines() or [""]
    return " \\\\\n".join("\\texttt{" + tex_text(line) + "}" for line in lines)


class Steps:
    """The ordered steps, indexed by thesis step number (``steps[5].A``); iterate in order.

    ``symbol_names`` are the LaTeX names used when no others are given."""

    def __init__(self, steps, symbol_names=None):
        self._steps = tuple(steps)
        self.symbol_names = dict(symbol_names or {})

    def __getitem__(self, number: int) -> Step:
        return self.get(number)

    def get(self, number: int) -> Step:
        for s in self._steps:
            if s.number == number:
                return s
        raise KeyError(number)

    def __iter__(self):
        return iter(self._steps)

    def __len__(self):
        return len(self._steps)

    def __repr__(self):
        return f"Steps({', '.join(str(s.number) for s in self._steps)})"

    def to_markdown(self, symbol_names=None) -> str:
        names = self.symbol_names if symbol_names is None else symbol_names
        return "\n".join(s.to_markdown(names) for s in self._steps)

    def to_latex(self, symbol_names=None) -> str:
        """The steps as LaTeX body text (needs ``amsmath``); see :func:`latex_document`."""
        names = self.symbol_names if symbol_names is None else symbol_names
        return "\n\n".join(s.to_latex(names) for s in self._steps)


def latex_document(body: str) -> str:
    """A complete LaTeX document around ``body`` (article, amsmath, amssymb)."""
    return ("\\documentclass{article}\n\\usepackage{amsmath}\n\\usepackage{amssymb}\n"
            "\\allowdisplaybreaks\n\\begin{document}\n" + body + "\n\\end{document}\n")
