"""The one parser for text that reaches nhgait from a scene file or the API.

Every expression string — Lagrangian, constraints, forces, input laws, parameter values,
initial values, named quantities, task values — is parsed here with Python's :mod:`ast` and
the sympy expression is built node by node. Nothing is evaluated: no ``eval``, ``sympify`` or
``parse_expr`` sees user text. Allowed are

* numbers (int and float literals), ``pi`` and ``E``;
* names: the symbols the caller passes (coordinates, velocities ``<q>_dot``, parameters,
  inputs, ``t``), and — where the caller allows it — new plain identifiers (reported by the
  caller, e.g. as undeclared inputs or unknown symbols);
* ``+ - * / **`` and unary ``+ -``;
* calls of the functions in :data:`FUNCTIONS` with positional arguments.

Anything else — attribute access, subscripts, lambdas, comprehensions, strings, keywords,
comparisons, walrus, f-strings, names starting with ``_`` — is a problem naming the offending
text. Size limits keep a hostile input from costing more than milliseconds: at most
:data:`MAX_LENGTH` characters, :data:`MAX_NODES` syntax nodes, nesting depth
:data:`MAX_DEPTH`, and integer exponents of magnitude at most :data:`MAX_EXPONENT`.
"""
from __future__ import annotations

import ast
import io
import keyword
import math
import tokenize
import unicodedata

import sympy as sp

from ...errors import ModelError

__all__ = ["FUNCTIONS", "CONSTANTS", "parse_expression", "parse_number", "expression_problems",
           "finite_or_nan", "MAX_LENGTH", "MAX_NODES", "MAX_DEPTH", "MAX_EXPONENT", "MAX_MAGNITUDE",
           "magnitude_problem", "name_clashes", "normalised_names"]

#: function name → (sympy function, allowed argument counts; None = two or more)
FUNCTIONS = {
    **{name: (getattr(sp, name), (1,)) for name in (
        "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "sinh", "cosh", "tanh",
        "exp", "log", "sqrt", "Abs", "sign", "Heaviside")},
    "atan2": (sp.atan2, (2,)),
    "Min": (sp.Min, None),
    "Max": (sp.Max, None),
}
#: constant name → value
CONSTANTS = {"pi": sp.pi, "E": sp.E}

MAX_LENGTH = 50_000
MAX_NODES = 50_000
MAX_DEPTH = 100
MAX_EXPONENT = 1_000
#: largest exact number (decimal digits of numerator or denominator) an expression may build
MAX_DIGITS = 300
#: largest magnitude of a number nhgait accepts (a parameter, an initial value, a target, a
#: constant of an expression, a URDF mass): a coordinate of 1e15 m keeps no digit below 0.1 m in
#: double precision, and products of a few values at this bound stay far from the 1.8e308
#: where doubles overflow (m = 1e308 made the kinetic metric's eigenvalues undefined)
MAX_MAGNITUDE = 1e15

_OPERATOR_HINT = {ast.BitXor: "'^' is not a power: write '**'", ast.Mod: "'%' is not supported",
                  ast.FloorDiv: "'//' is not supported: write '/'",
                  ast.MatMult: "'@' is not supported"}


class _Reject(Exception):
    """One problem with the text; the message names the offending part."""


def _shorten(text: str, limit: int = 60) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 1] + "…"


class _Builder:
    """Build a sympy expression from an ``ast`` tree, allowing only the grammar above."""

    def __init__(self, source: str, names: dict, allow_unknown: bool):
        self.source = source
        self.names = names if all(str(k).isascii() for k in names) else normalised_names(names)
        self.allow_unknown = allow_unknown
        self.unknown: dict = {}

    def segment(self, node) -> str:
        return _shorten(ast.get_source_segment(self.source, node) or type(node).__name__)

    def build(self, node, depth: int = 0):
        if depth > MAX_DEPTH:
            raise _Reject(f"nested more than {MAX_DEPTH} levels deep")
        method = getattr(self, f"_{type(node).__name__}", None)
        if method is None:
            raise _Reject(f"{self._describe(node)} is not allowed: {self.segment(node)!r}")
        out = method(node, depth + 1)
        if out.is_Rational and max(_digits(out.p), _digits(out.q)) > MAX_DIGITS:
            raise _Reject(f"number with more than {MAX_DIGITS} digits: {self.segment(node)!r}")
        if not out.free_symbols:
            self._judge_magnitude(out, node)
        return out

    def _judge_magnitude(self, value, node):
        """The magnitude guard on a number the user wrote (a literal or a constant part such as
        ``1e10*1e10``), not on one sympy folds: 50*(x + 0.75) inside exp becomes
        1.93e16*exp(50*x), which is the user's smooth wall, not a number beyond the bound."""
        number = _float_value(value)
        if math.isfinite(number) and abs(number) > MAX_MAGNITUDE:
            raise _Reject(f"a constant in {_shorten(self.source)!r} exceeds {MAX_MAGNITUDE:.0e} in "
                          f"magnitude, the largest number nhgait accepts ({self.segment(node)!r})")

    @staticmethod
    def _describe(node) -> str:
        kinds = {ast.Attribute: "attribute access", ast.Subscript: "subscripting",
                 ast.Lambda: "a lambda", ast.ListComp: "a comprehension",
                 ast.GeneratorExp: "a generator", ast.SetComp: "a comprehension",
                 ast.DictComp: "a comprehension", ast.NamedExpr: "an assignment (:=)",
                 ast.JoinedStr: "an f-string", ast.Compare: "a comparison",
                 ast.BoolOp: "a logical operator", ast.IfExp: "a conditional expression",
                 ast.Starred: "unpacking", ast.List: "a list", ast.Tuple: "a tuple",
                 ast.Dict: "a dict", ast.Set: "a set", ast.Await: "await", ast.Yield: "yield"}
        return kinds.get(type(node), f"syntax {type(node).__name__}")

    # -- leaves -------------------------------------------------------------------------
    def _Constant(self, node, depth):
        v = node.value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise _Reject(f"only numbers are allowed as literals, got {self.segment(node)!r}")
        if isinstance(v, float):
            if not math.isfinite(v):
                raise _Reject(f"number {self.segment(node)!r} is not finite")
            return sp.Float(repr(v))
        return sp.Integer(v)

    def _Name(self, node, depth):
        name = node.id
        if name in self.names:
            return self.names[name]
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS:
            raise _Reject(f"function {name!r} used without arguments")
        if name.startswith("_") or keyword.iskeyword(name):
            raise _Reject(f"name {name!r} is not allowed")
        if not self.allow_unknown:
            raise _Reject(f"unknown name {name!r}")
        return self.unknown.setdefault(name, sp.Symbol(name, real=True))

    # -- operators ----------------------------------------------------------------------
    def _UnaryOp(self, node, depth):
        x = self.build(node.operand, depth)
        if isinstance(node.op, ast.USub):
            return -x
        if isinstance(node.op, ast.UAdd):
            return x
        raise _Reject(f"operator {self.segment(node)!r} is not allowed")

    def _BinOp(self, node, depth):
        op = type(node.op)
        if op in _OPERATOR_HINT:
            raise _Reject(f"{_OPERATOR_HINT[op]} (in {self.segment(node)!r})")
        if op in (ast.Add, ast.Sub):
            return sp.Add(*[t if positive
                            else -t for t, positive in self._chain(node, depth, ast.Add, ast.Sub)])
        if op in (ast.Mult, ast.Div):
            factors = [f if positive else sp.Pow(f, -1)
                       for f, positive in self._chain(node, depth, ast.Mult, ast.Div)]
            self._judge_magnitude(sp.Mul(*[f for f in factors if not f.free_symbols]), node)
            return sp.Mul(*factors)
        if op is ast.Pow:
            return self._power(self.build(node.left, depth), self.build(node.right, depth), node)
        raise _Reject(f"operator in {self.segment(node)!r} is not allowed")

    def _chain(self, node, depth, plus, minus):
        """Operands of a left-associated chain a ± b ± c … (or a ×/÷ b …) with their signs,
        walked iteratively: a sum of many terms is one level of nesting, not one per term."""
        operands = []
        while isinstance(node, ast.BinOp) and isinstance(node.op, (plus, minus)):
            operands.append((node.right, isinstance(node.op, plus)))
            node = node.left
        operands.append((node, True))
        out = []
        for operand, positive in reversed(operands):
            value = self.build(operand, depth)
            if not positive and minus is ast.Div and value.is_Number and value == 0:
                raise _Reject(f"division by zero: {self.segment(operand)!r}")
            out.append((value, positive))
        return out

    def _power(self, base, exponent, node):
        if exponent.is_Number and not exponent.is_Integer:
            return sp.Pow(base, exponent)
        if exponent.is_Integer:
            if abs(int(exponent)) > MAX_EXPONENT:
                raise _Reject(f"exponent {_shorten(str(exponent), 20)} is too large (at most "
                              f"{MAX_EXPONENT} in magnitude): {self.segment(node)!r}")
            if base.is_Number and base == 0 and exponent < 0:
                raise _Reject(f"division by zero: {self.segment(node)!r}")
            if (base.is_Rational
                and abs(int(exponent)) * max(_digits(base.p), _digits(base.q)) > 2 * MAX_DIGITS):
                raise _Reject(f"number with more than {MAX_DIGITS} digits: {self.segment(node)!r}")
            return sp.Pow(base, exponent)
        if exponent.is_number:
            # a constant exponent such as pi or sqrt(2): keep it unevaluated if the base is numeric
            return sp.Pow(base, exponent, evaluate=not base.is_number)
        return sp.Pow(base, exponent)

    def _Call(self, node, depth):
        if not isinstance(node.func, ast.Name):
            raise _Reject(f"only calls of named functions are allowed: {self.segment(node)!r}")
        name = node.func.id
        if name not in FUNCTIONS:
            raise _Reject(f"unknown function {name!r} (allowed: {', '.join(sorted(FUNCTIONS))})")
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise _Reject(f"{name}() takes positional arguments only: {self.segment(node)!r}")
        func, arities = FUNCTIONS[name]
        count = len(node.args)
        if (arities is None and count < 2) or (arities is not None and count not in arities):
            want = "two or more" if arities is None else " or ".join(map(str, arities))
            raise _Reject(f"{name}() takes {want} argument(s), got {count}: {self.segment(node)!r}")
        args = [self.build(a, depth) for a in node.args]
        return func(*args)


def normalised_names(names: dict) -> dict:
    """``names`` keyed by their NFKC normal form, the form Python's parser gives every
    identifier it reads (the ligature "ﬁ" is read as "fi"): a name declared as "ﬁ" is found
    where the text writes ﬁ. Two names of one normal form are refused where they are declared
    (:func:`name_clashes`)."""
    return {unicodedata.normalize("NFKC", str(k)): v for k, v in names.items()}


def name_clashes(names) -> list:
    """One sentence per group of ``names`` that differ only by Unicode normalisation (NFKC):
    Python's parser reads them as one name, so the text could not tell them apart."""
    groups: dict = {}
    for name in names:
        groups.setdefault(unicodedata.normalize("NFKC", name), []).append(name)
    return [f"names {' and '.join(map(repr, group))} differ only by Unicode normalisation (both "
            f"read as {key!r}): they are one name — rename one"
            for key, group in groups.items() if len(set(group)) > 1]


def _digits(value: int) -> int:
    """Decimal digits of an integer, from its bit length (no conversion to text)."""
    return int(abs(int(value)).bit_length() * 0.30103) + 1


def _syntax_tree(text: str):
    """``ast`` tree of ``text`` or a :class:`_Reject` (bad syntax, too deep for the parser)."""
    try:
        return ast.parse(text, mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else ""
        raise _Reject(f"cannot parse: syntax error{where} ({exc.msg})") from None
    except (RecursionError, MemoryError, ValueError) as exc:
        raise _Reject(f"cannot be parsed ({type(exc).__name__}: nested or chained too deeply)") from None


def _top_level_terms(source: str) -> list:
    """``source`` split at its top-level binary ``+``/``-`` into (term text, sign) pairs, with
    the tokenizer (a lexer: nothing is evaluated). Python's parser nests a sum of n terms n
    levels deep, so a Lagrangian with thousands of terms is parsed term by term. Returns
    [(source, True)] when the text does not tokenize (the parser then names the error)."""
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return [(source, True)]
    terms, start, positive, depth, previous = [], 0, True, 0, None
    for tok in tokens:
        if tok.type == tokenize.OP and tok.string in "([{":
            depth += 1
        elif tok.type == tokenize.OP and tok.string in ")]}":
            depth -= 1
        elif (tok.type == tokenize.OP and tok.string in "+-" and depth == 0 and previous is not None
              and (previous.type in (tokenize.NAME, tokenize.NUMBER, tokenize.STRING)
                   or previous.string in (")", "]", "}"))):
            terms.append((source[start:tok.start[1]], positive))
            start, positive = tok.end[1], tok.string == "+"
        if tok.type not in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER, tokenize.COMMENT):
            previous = tok
    terms.append((source[start:], positive))
    return terms


def _build(source: str, names: dict, allow_unknown: bool):
    """The sympy expression of ``source``: each top-level term parsed and built on its own,
    within the size limits; raises :class:`_Reject`."""
    if len(source) > MAX_LENGTH:
        raise _Reject(f"text of {len(source)} characters is too long (at most {MAX_LENGTH})")
    try:
        pieces = [(source, True, _syntax_tree(source))]
    except _Reject as exc:
        if "nested or chained too deeply" not in str(exc):
            raise
        pieces = [(text, positive, None) for text, positive in _top_level_terms(source)]
    terms, count, unknown = [], 0, {}
    for text, positive, tree in pieces:
        builder = _Builder(text.strip(), names, allow_unknown)
        builder.unknown = unknown
        tree = tree if tree is not None else _syntax_tree(builder.source)
        for _ in ast.walk(tree):
            count += 1
            if count > MAX_NODES:
                raise _Reject(f"expression has more than {MAX_NODES} parts")
        value = builder.build(tree.body)
        terms.append(value if positive else -value)
    return sp.Add(*terms)


def expression_problems(text: str, names: dict, where: str, problems: list, *,
                        allow_unknown: bool = False):
    """Parse ``text``; append one sentence per problem to ``problems``.

    Parameters
    ----------
    text : str
        The expression.
    names : mapping name → sympy Symbol
        The symbols the expression may use (coordinates, velocities, parameters, ``t`` …).
    where : str
        Where the text comes from, e.g. ``"constraint 2"``; starts every problem.
    allow_unknown : bool
        Accept other identifiers as new real symbols (the caller reports or uses them).

    Returns
    -------
    sympy expression, or None when a problem was found.
    """
    if not isinstance(text, str):
        problems.append(f"{where}: expected an expression string, got {type(text).__name__} "
                        f"{_shorten(repr(text))}")
        return None
    source = " ".join(text.split())  # multi-line TOML strings
    if not source:
        problems.append(f"{where}: empty expression")
        return None
    try:
        expr = _build(source, names, allow_unknown)
    except _Reject as exc:
        problems.append(f"{where}: {exc}")
        return None
    except (RecursionError, MemoryError, OverflowError, ValueError, TypeError, ZeroDivisionError) as exc:
        problems.append(f"{where}: cannot be built ({type(exc).__name__}) from {_shorten(source)!r}")
        return None
    if expr.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
        problems.append(f"{where}: {_shorten(source)!r} is infinite or undefined")
        return None
    if expr.has(sp.I):
        problems.append(f"{where}: {_shorten(source)!r} is not real")
        return None
    constants = [float(x) for x in expr.atoms(sp.Float, sp.Integer)] + [
        _float_value(c) for c in expr.atoms(sp.Function, sp.Pow) if not c.free_symbols]
    if any(not math.isfinite(v) for v in constants):   # folded constants: finite doubles only
        problems.append(f"{where}: a constant in {_shorten(source)!r} is too large or undefined")
        return None
    return expr


def parse_expression(text: str, names: dict, where: str, *, allow_unknown: bool = False):
    """:func:`expression_problems` that raises one :class:`ModelError` instead."""
    problems: list = []
    expr = expression_problems(text, names, where, problems, allow_unknown=allow_unknown)
    if problems:
        raise ModelError(problems, title="invalid expression")
    return expr


def finite_or_nan(value) -> float:
    """``float(value)``, or nan when that is not a finite number (a string that is not a number,
    an integer too large for a float, ±inf, nan)."""
    try:
        out = float(value)
    except (ValueError, OverflowError):
        return math.nan
    return out if math.isfinite(out) else math.nan


def number_problems(value, where: str, problems: list, names: dict | None = None) -> float:
    """A finite real number from a TOML/JSON value: a number, or a constant expression such as
    ``"sqrt((0.3 + 0.2 + 2*0.1)/0.5)"`` or ``"10*pi"``. Returns nan after appending a problem."""
    if isinstance(value, bool):
        problems.append(f"{where}: expected a number, got {value!r}")
        return math.nan
    if isinstance(value, (int, float)):
        out = finite_or_nan(value)
        if math.isnan(out):
            problems.append(f"{where}: {value!r} is not finite")
        return magnitude_problem(out, where, problems)
    if not isinstance(value, str):
        problems.append(f"{where}: expected a number or a constant expression, got "
                        f"{type(value).__name__} {_shorten(repr(value))}")
        return math.nan
    sub: list = []
    expr = expression_problems(value, names or {}, where, sub, allow_unknown=True)
    if sub:
        problems.extend(sub)
        return math.nan
    if expr.free_symbols:
        problems.append(f"{where}: {_shorten(value)!r} is not a number (it contains "
                        f"{', '.join(sorted(s.name for s in expr.free_symbols))})")
        return math.nan
    out = _float_value(expr)
    if math.isfinite(out):  # the magnitude is safe: now the correctly rounded value
        out = float(sp.N(expr, 20))
    if not math.isfinite(out):
        problems.append(f"{where}: {_shorten(value)!r} is not a finite real number")
        return math.nan
    return magnitude_problem(out, where, problems)


def magnitude_problem(value: float, where: str, problems: list) -> float:
    """``value``, or nan after appending a problem when it exceeds :data:`MAX_MAGNITUDE` in
    magnitude (naming ``where`` and the bound)."""
    if abs(value) > MAX_MAGNITUDE:
        problems.append(f"{where}: {value:.6g} exceeds {MAX_MAGNITUDE:.0e} in magnitude, the largest number "
                        "nhgait accepts (beyond it double precision keeps no digit below 0.1 and products "
                        "of such values overflow)")
        return math.nan
    return value


_MATH = {sp.sin: math.sin, sp.cos: math.cos, sp.tan: math.tan, sp.asin: math.asin,
         sp.acos: math.acos, sp.atan: math.atan, sp.sinh: math.sinh, sp.cosh: math.cosh,
         sp.tanh: math.tanh, sp.exp: math.exp, sp.log: math.log, sp.atan2: math.atan2,
         sp.Abs: abs, sp.sign: lambda x: float((x > 0) - (x < 0)),
         sp.Heaviside: lambda x: 1.0 if x > 0 else (0.0 if x < 0 else 0.5),
         sp.cot: lambda x: 1 / math.tan(x), sp.sec: lambda x: 1 / math.cos(x),
         sp.csc: lambda x: 1 / math.sin(x), sp.Min: min, sp.Max: max}


def _float_value(expr) -> float:
    """Value of a constant expression in double precision (nan/inf instead of a hang: mpmath
    would try to evaluate exp(exp(exp(exp(100)))) exactly)."""
    def ev(e):
        if e.is_Number or e.is_NumberSymbol:
            return float(e)
        args = [ev(a) for a in e.args]
        if e.is_Add:
            return math.fsum(args)
        if e.is_Mul:
            return math.prod(args)
        if e.is_Pow:
            return math.pow(*args)
        if e.func in _MATH:
            return float(_MATH[e.func](*args))
        return math.nan
    try:
        return ev(expr)
    except (OverflowError, ValueError, ZeroDivisionError, TypeError, RecursionError):
        return math.nan


def parse_number(value, where: str) -> float:
    """:func:`number_problems` that raises one :class:`ModelError` instead."""
    problems: list = []
    out = number_problems(value, where, problems)
    if problems:
        raise ModelError(problems, title="invalid number")
    return out
