"""Butcher tableaus of the embedded explicit Runge–Kutta pairs used by :mod:`.compiled`.

Data only (no integrator code here). Each pair is stored as exact rationals where the
literature gives them and as the published 30-digit decimals otherwise, and turned into
double-precision arrays by :func:`tableau`. The order conditions of every weight vector (and of
the continuous extension, for every θ) are checked against Butcher's rooted-tree conditions in
``tests/dynamics/test_rk_tableaus.py``.

* ``"DOPRI5"``: Dormand & Prince, *A family of embedded Runge–Kutta formulae*, J. Comput. Appl.
  Math. 6 (1980) 19–26 — the 5(4) pair with 7 stages, first-same-as-last (stage 7 is f(t+h, y₁));
  dense output of order 4 due to Shampine (1986), as given in Hairer, Nørsett & Wanner, *Solving
  Ordinary Differential Equations I* (2nd ed., 1993), §II.5–II.6.
* ``"DOP853"``: Prince & Dormand, *High order embedded Runge–Kutta formulae*, J. Comput. Appl.
  Math. 7 (1981) 67–75, in the 8(5,3) form of Hairer, Nørsett & Wanner (1993), §II.10: 12 stages,
  an 8th-order solution, a 5th-order and a 3rd-order error estimate combined as
  err = err₅² / √(err₅² + 0.01 err₃²), and a 7th-order continuous extension that needs the
  stage f(t+h, y₁) and three more stages (c = 0.1, 0.2, 7/9).

Conventions of :class:`Tableau` (all arrays float64)
----------------------------------------------------
Stages are numbered 0 … s_ext−1 in the order they are computed:

* ``0 … s_step−1``: the stages of one step (stage 0 is f(t, y));
* ``i_new``: the stage f(t+h, y₁) at the new point (row ``a[i_new]`` = b). For DOPRI5 it is the
  last step stage (FSAL); for DOP853 it is stage 12, computed after the step is accepted;
* the remaining stages up to ``s_ext`` serve only the continuous extension.

``a`` (s_ext, s_ext) strictly lower triangular, ``c`` (s_ext,), ``b`` (s_ext,) the propagating
weights, ``e`` (s_ext,) the error weights of the main estimate (b − b̂), ``e3`` (s_ext,) the 3rd-order
estimate (DOP853 only, else None). ``dense`` (s_ext, degree): the continuous extension
y(t + θh) = y + h Σᵢ kᵢ Σ_d dense[i, d] θ^(d+1), a polynomial of degree ``degree`` in θ.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction as F

import numpy as np

__all__ = ["Tableau", "tableau", "exact_tableau", "TABLEAU_NAMES"]

TABLEAU_NAMES = ("DOP853", "DOPRI5")


@dataclass(frozen=True, eq=False)
class Tableau:
    """An embedded explicit RK pair with a continuous extension (see the module docstring)."""

    name: str
    order: int              # order of the propagated solution
    error_order: int        # order of the embedded (lower-order) solution
    dense_order: int        # order of the continuous extension
    s_step: int             # stages evaluated per step (including the FSAL stage for DOPRI5)
    i_new: int              # index of the stage f(t + h, y1)
    s_ext: int              # all stages, including those of the continuous extension only
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    e: np.ndarray
    e3: np.ndarray | None
    dense: np.ndarray
    stability_limit: float  # |hλ| on the negative real axis beyond which the method is unstable
    i_stiff: int            # a step stage with c = 1 other than i_new (stiffness detection)


# ---------------------------------------------------------------------------------------------
# Dormand–Prince 5(4), Shampine's dense output (exact rationals)
# ---------------------------------------------------------------------------------------------
_DOPRI5_C = [F(0), F(1, 5), F(3, 10), F(4, 5), F(8, 9), F(1), F(1)]
_DOPRI5_A = {
    1: {0: F(1, 5)},
    2: {0: F(3, 40), 1: F(9, 40)},
    3: {0: F(44, 45), 1: F(-56, 15), 2: F(32, 9)},
    4: {0: F(19372, 6561), 1: F(-25360, 2187), 2: F(64448, 6561), 3: F(-212, 729)},
    5: {0: F(9017, 3168), 1: F(-355, 33), 2: F(46732, 5247), 3: F(49, 176), 4: F(-5103, 18656)},
    6: {0: F(35, 384), 2: F(500, 1113), 3: F(125, 192), 4: F(-2187, 6784), 5: F(11, 84)},
}
_DOPRI5_BHAT = {0: F(5179, 57600), 2: F(7571, 16695), 3: F(393, 640), 4: F(-92097, 339200),
                5: F(187, 2100), 6: F(1, 40)}
#: Shampine's dense-output coefficients (the fifth term of the nested Hermite form)
_DOPRI5_D = {0: F(-12715105075, 11282082432), 2: F(87487479700, 32700410799),
             3: F(-10690763975, 1880347072), 4: F(701980252875, 199316789632),
             5: F(-1453857185, 822651844), 6: F(69997945, 29380423)}

# ---------------------------------------------------------------------------------------------
# Dormand–Prince 8(5,3) (published 30-digit decimals; stages numbered from 0)
# ---------------------------------------------------------------------------------------------
_DOP853_C = {1: "0.526001519587677318785587544488e-01", 2: "0.789002279381515978178381316732e-01",
             3: "0.118350341907227396726757197510e+00", 4: "0.281649658092772603273242802490e+00",
             5: F(1, 3), 6: F(1, 4), 7: F(4, 13), 8: F(127, 195), 9: F(3, 5), 10: F(6, 7),
             11: F(1), 12: F(1), 13: F(1, 10), 14: F(1, 5), 15: F(7, 9)}
_DOP853_A = {
    1: {0: "5.26001519587677318785587544488e-2"},
    2: {0: "1.97250569845378994544595329183e-2", 1: "5.91751709536136983633785987549e-2"},
    3: {0: "2.95875854768068491816892993775e-2", 2: "8.87627564304205475450678981324e-2"},
    4: {0: "2.41365134159266685502369798665e-1", 2: "-8.84549479328286085344864962717e-1",
        3: "9.24834003261792003115737966543e-1"},
    5: {0: F(1, 27), 3: "1.70828608729473871279604482173e-1",
        4: "1.25467687566822425016691814123e-1"},
    6: {0: F(19, 512), 3: "1.70252211019544039314978060272e-1",
        4: "6.02165389804559606850219397283e-2", 5: F(-9, 512)},
    7: {0: "3.70920001185047927108779319836e-2", 3: "1.70383925712239993810214054705e-1",
        4: "1.07262030446373284651809199168e-1", 5: "-1.53194377486244017527936158236e-2",
        6: "8.27378916381402288758473766002e-3"},
    8: {0: "6.24110958716075717114429577812e-1", 3: "-3.36089262944694129406857109825e0",
        4: "-8.68219346841726006818189891453e-1", 5: "2.75920996994467083049415600797e1",
        6: "2.01540675504778934086186788979e1", 7: "-4.34898841810699588477366255144e1"},
    9: {0: "4.77662536438264365890433908527e-1", 3: "-2.48811461997166764192642586468e0",
        4: "-5.90290826836842996371446475743e-1", 5: "2.12300514481811942347288949897e1",
        6: "1.52792336328824235832596922938e1", 7: "-3.32882109689848629194453265587e1",
        8: "-2.03312017085086261358222928593e-2"},
    10: {0: "-9.3714243008598732571704021658e-1", 3: "5.18637242884406370830023853209e0",
         4: "1.09143734899672957818500254654e0", 5: "-8.14978701074692612513997267357e0",
         6: "-1.85200656599969598641566180701e1", 7: "2.27394870993505042818970056734e1",
         8: "2.49360555267965238987089396762e0", 9: "-3.0467644718982195003823669022e0"},
    11: {0: "2.27331014751653820792359768449e0", 3: "-1.05344954667372501984066689879e1",
         4: "-2.00087205822486249909675718444e0", 5: "-1.79589318631187989172765950534e1",
         6: "2.79488845294199600508499808837e1", 7: "-2.85899827713502369474065508674e0",
         8: "-8.87285693353062954433549289258e0", 9: "1.23605671757943030647266201528e1",
         10: "6.43392746015763530355970484046e-1"},
    # 12: f(t + h, y1), filled with b below
    13: {0: "5.61675022830479523392909219681e-2", 6: "2.53500210216624811088794765333e-1",
         7: "-2.46239037470802489917441475441e-1", 8: "-1.24191423263816360469010140626e-1",
         9: "1.5329179827876569731206322685e-1", 10: "8.20105229563468988491666602057e-3",
         11: "7.56789766054569976138603589584e-3", 12: "-8.298e-3"},
    14: {0: "3.18346481635021405060768473261e-2", 5: "2.83009096723667755288322961402e-2",
         6: "5.35419883074385676223797384372e-2", 7: "-5.49237485713909884646569340306e-2",
         10: "-1.08347328697249322858509316994e-4", 11: "3.82571090835658412954920192323e-4",
         12: "-3.40465008687404560802977114492e-4", 13: "1.41312443674632500278074618366e-1"},
    15: {0: "-4.28896301583791923408573538692e-1", 5: "-4.69762141536116384314449447206e0",
         6: "7.68342119606259904184240953878e0", 7: "4.06898981839711007970213554331e0",
         8: "3.56727187455281109270669543021e-1", 12: "-1.39902416515901462129418009734e-3",
         13: "2.9475147891527723389556272149e0", 14: "-9.15095847217987001081870187138e0"},
}
_DOP853_B = {0: "5.42937341165687622380535766363e-2", 5: "4.45031289275240888144113950566e0",
             6: "1.89151789931450038304281599044e0", 7: "-5.8012039600105847814672114227e0",
             8: "3.1116436695781989440891606237e-1", 9: "-1.52160949662516078556178806805e-1",
             10: "2.01365400804030348374776537501e-1", 11: "4.47106157277725905176885569043e-2"}
#: b − b̂₅ (5th-order error estimate)
_DOP853_E5 = {0: "0.1312004499419488073250102996e-01", 5: "-0.1225156446376204440720569753e+01",
              6: "-0.4957589496572501915214079952e+00", 7: "0.1664377182454986536961530415e+01",
              8: "-0.3503288487499736816886487290e+00", 9: "0.3341791187130174790297318841e+00",
              10: "0.8192320648511571246570742613e-01", 11: "-0.2235530786388629525884427845e-01"}
#: weights of the 3rd-order solution b̂₃ (stages 0, 8, 11)
_DOP853_B3 = {0: "0.244094488188976377952755905512e+00", 8: "0.733846688281611857341361741547e+00",
              11: "0.220588235294117647058823529412e-01"}
#: the four coefficient rows (d₄ … d₇) of the 7th-order continuous extension
_DOP853_D = [
    {0: "-0.84289382761090128651353491142e+01", 5: "0.56671495351937776962531783590e+00",
     6: "-0.30689499459498916912797304727e+01", 7: "0.23846676565120698287728149680e+01",
     8: "0.21170345824450282767155149946e+01", 9: "-0.87139158377797299206789907490e+00",
     10: "0.22404374302607882758541771650e+01", 11: "0.63157877876946881815570249290e+00",
     12: "-0.88990336451333310820698117400e-01", 13: "0.18148505520854727256656404962e+02",
     14: "-0.91946323924783554000451984436e+01", 15: "-0.44360363875948939664310572000e+01"},
    {0: "0.10427508642579134603413151009e+02", 5: "0.24228349177525818288430175319e+03",
     6: "0.16520045171727028198505394887e+03", 7: "-0.37454675472269020279518312152e+03",
     8: "-0.22113666853125306036270938578e+02", 9: "0.77334326684722638389603898808e+01",
     10: "-0.30674084731089398182061213626e+02", 11: "-0.93321305264302278729567221706e+01",
     12: "0.15697238121770843886131091075e+02", 13: "-0.31139403219565177677282850411e+02",
     14: "-0.93529243588444783865713862664e+01", 15: "0.35816841486394083752465898540e+02"},
    {0: "0.19985053242002433820987653617e+02", 5: "-0.38703730874935176555105901742e+03",
     6: "-0.18917813819516756882830838328e+03", 7: "0.52780815920542364900561016686e+03",
     8: "-0.11573902539959630126141871134e+02", 9: "0.68812326946963000169666922661e+01",
     10: "-0.10006050966910838403183860980e+01", 11: "0.77771377980534432092869265740e+00",
     12: "-0.27782057523535084065932004339e+01", 13: "-0.60196695231264120758267380846e+02",
     14: "0.84320405506677161018159903784e+02", 15: "0.11992291136182789328035130030e+02"},
    {0: "-0.25693933462703749003312586129e+02", 5: "-0.15418974869023643374053993627e+03",
     6: "-0.23152937917604549567536039109e+03", 7: "0.35763911791061412378285349910e+03",
     8: "0.93405324183624310003907691704e+02", 9: "-0.37458323136451633156875139351e+02",
     10: "0.10409964950896230045147246184e+03", 11: "0.29840293426660503123344363579e+02",
     12: "-0.43533456590011143754432175058e+02", 13: "0.96324553959188282948394950600e+02",
     14: "-0.39177261675615439165231486172e+02", 15: "-0.14972683625798562581422125276e+03"},
]


def _q(value) -> F:
    """An exact rational from a Fraction or a decimal string."""
    return value if isinstance(value, F) else F(Decimal(value))


def _vector(entries: dict, size: int) -> list:
    out = [F(0)] * size
    for i, v in entries.items():
        out[i] = _q(v)
    return out


def _poly_mul(p, r):
    """Product of two polynomials in θ (coefficient lists, lowest power first)."""
    out = [F(0)] * (len(p) + len(r) - 1)
    for i, x in enumerate(p):
        for j, y in enumerate(r):
            out[i + j] += x * y
    return out


def _nested_extension(blocks: list, size: int) -> list:
    """Continuous extension of the nested Hermite form used by both pairs,

        y(θ) − y = θ(r₂ + θ'(r₃ + θ(r₄ + θ'(r₅ + θ(r₆ + …))))),  θ' = 1 − θ,

    where each r is a stage combination h Σᵢ rᵢ kᵢ (``blocks[j]`` a list over stages).
    Returns, per stage, the coefficients of θ¹ … θᵈ."""
    per_stage = [[F(0)] for _ in range(size)]
    for depth in range(len(blocks) - 1, -1, -1):       # Horner from the innermost block
        factor = [F(0), F(1)] if depth % 2 == 0 else [F(1), F(-1)]
        per_stage = [_poly_mul([blocks[depth][i]] if depth == len(blocks) - 1 else
                               _poly_add(per_stage[i], [blocks[depth][i]]), factor)
                     for i in range(size)]
    degree = max(len(p) for p in per_stage) - 1
    return [[p[d] if d < len(p) else F(0) for d in range(1, degree + 1)] for p in per_stage]


def _poly_add(p, r):
    n = max(len(p), len(r))
    return [(p[i] if i < len(p) else F(0)) + (r[i] if i < len(r) else F(0)) for i in range(n)]


def _hermite_blocks(b: list, i_new: int, extra: list) -> list:
    """r₂ = b, r₃ = e₀ − b, r₄ = b − e_new − r₃, then the method's own blocks (stage vectors)."""
    size = len(b)
    k0 = [F(1) if i == 0 else F(0) for i in range(size)]
    knew = [F(1) if i == i_new else F(0) for i in range(size)]
    r2 = list(b)
    r3 = [k0[i] - b[i] for i in range(size)]
    r4 = [b[i] - knew[i] - r3[i] for i in range(size)]
    return [r2, r3, r4] + extra


def exact_tableau(name: str) -> dict:
    """The tableau as exact rationals: keys c, a (list of rows), b, e, e3, bhat, b3, dense."""
    if name == "DOPRI5":
        s = 7
        c = list(_DOPRI5_C)
        a = [_vector(_DOPRI5_A.get(i, {}), s) for i in range(s)]
        b = list(a[6])
        bhat = _vector(_DOPRI5_BHAT, s)
        e = [b[i] - bhat[i] for i in range(s)]
        blocks = _hermite_blocks(b, 6, [_vector(_DOPRI5_D, s)])
        return dict(c=c, a=a, b=b, bhat=bhat, e=e, e3=None, b3=None,
                    dense=_nested_extension(blocks, s))
    if name == "DOP853":
        s = 16
        c = [F(0)] + [_q(_DOP853_C[i]) for i in range(1, s)]
        b = _vector(_DOP853_B, s)
        a = [b if i == 12 else _vector(_DOP853_A.get(i, {}), s) for i in range(s)]
        e = _vector(_DOP853_E5, s)
        b3 = _vector(_DOP853_B3, s)
        e3 = [b[i] - b3[i] for i in range(s)]
        bhat = [b[i] - e[i] for i in range(s)]
        blocks = _hermite_blocks(b, 12, [_vector(row, s) for row in _DOP853_D])
        return dict(c=c, a=a, b=b, bhat=bhat, e=e, e3=e3, b3=b3, dense=_nested_extension(blocks, s))
    raise ValueError(f"unknown tableau {name!r} (choose from {', '.join(TABLEAU_NAMES)})")


@functools.cache
def tableau(name: str) -> Tableau:
    """The double-precision :class:`Tableau` of ``"DOP853"`` or ``"DOPRI5"``."""
    ex = exact_tableau(name)

    def arr(v):
        return np.array([float(x) for x in v])

    common = dict(c=arr(ex["c"]), a=np.array([[float(x) for x in row] for row in ex["a"]]),
                  b=arr(ex["b"]), e=arr(ex["e"]), e3=None if ex["e3"] is None else arr(ex["e3"]),
                  dense=np.array([[float(x) for x in row] for row in ex["dense"]]))
    if name == "DOPRI5":
        return Tableau(name=name, order=5, error_order=4, dense_order=4, s_step=7, i_new=6,
                       s_ext=7, stability_limit=3.3, i_stiff=5, **common)
    return Tableau(name=name, order=8, error_order=5, dense_order=7, s_step=12, i_new=12,
                   s_ext=16, stability_limit=6.1, i_stiff=11, **common)
