"""Intermediate objects of the 20 steps against the thesis's Examples 3.1 and 3.2, where the
thesis is right, and against the corrected forms where it is not (docs/thesis-errata.md).

Equalities are decided exactly: the difference is brought to the trig normal form of
``nhgait.dynamics.algebra.trig.trig_normal`` (canonical, so a zero difference returns 0).
For the snakeboard the thesis assumes J + J_r + 2J_w = m r² (eq. 3.55); we substitute it.
"""
import pytest
import sympy as sp

from nhgait.dynamics.algebra.trig import trig_normal

x, y, th, psi, phi = sp.symbols("x y theta psi phi", real=True)
m, r, J, Jr, Jw, Jphi, Jth = sp.symbols("m r J J_r J_w J_phi J_theta", real=True)
xd, yd, thd, psid, phid = sp.symbols("x_dot y_dot theta_dot psi_dot phi_dot", real=True)
p, pt_psi, pt_phi, pt_theta, Om = sp.symbols("p pt_psi pt_phi pt_theta Omega", real=True)
THESIS = {J: m * r**2 - Jr - 2 * Jw}      # the snakeboard's simplifying condition (3.55)


def same(a, b, subs=None):
    d = sp.sympify(a) - sp.sympify(b)
    if subs:
        d = d.xreplace(subs)
    return trig_normal(sp.expand(d)) == 0


def same_matrix(A, B, subs=None):
    A, B = sp.Matrix(A), sp.Matrix(B)
    return A.shape == B.shape and all(same(a, b, subs) for a, b in zip(A, B, strict=True))


@pytest.fixture(scope="module")
def uni_A(systems):
    from nhgait.dynamics import derive
    return derive(systems["unicycle"], "reduced", version="A")


@pytest.fixture(scope="module")
def uni_B(systems):
    from nhgait.dynamics import derive
    return derive(systems["unicycle"], "reduced", version="B")


@pytest.fixture(scope="module")
def board(models):
    return models["snakeboard"]["reduced"]


# ----------------------------------------------------------------------------- unicycle
def test_unicycle_symmetry_table_is_table_3_1(uni_B):
    rows = {c.fiber: c for c in uni_B.symmetry.candidates}
    assert rows[("x", "y", "theta")].verdict == "not full"              # ξ = (0, 0, 1)
    assert same_matrix(rows[("x", "y", "theta")].xi, [0, 0, 1])
    assert rows[("x", "y", "phi")].verdict == "full"
    assert uni_B.symmetry.chosen.fiber == ("x", "y", "phi")              # G = R² × S¹
    assert same_matrix(uni_B.steps[3].xi, [r * sp.cos(th), r * sp.sin(th), 1])  # 3.8


def test_unicycle_momentum_and_reconstruction(uni_A, uni_B):
    assert same(uni_B.steps[4].p[0], m * r * sp.cos(th) * xd + m * r * sp.sin(th) * yd + Jphi * phid)  # 3.9
    D = Jphi + m * r**2
    assert same_matrix(uni_A.steps[5].Gamma, [r * sp.cos(th) / D, r * sp.sin(th) / D, 1 / D])  # 3.13
    assert same_matrix(uni_B.steps[5].Gamma, [r / D, 0, 1 / D])                                # 3.36
    assert same_matrix(uni_B.steps[6].e, [r, 0, 1])                                   # 3.37
    assert all(e == 0 for e in uni_B.steps[5].A)                                               # A = 0
    assert uni_B.classification == "purely dynamic"


def test_unicycle_lagrangian_hamiltonian_and_equations(uni_B):
    assert same(uni_B.steps[8].l_c, ((Jphi + m * r**2) * Om**2 + Jth * thd**2) / 2)             # 3.17
    # 3.20
    assert same(uni_B.hamiltonian, (p**2 / (Jphi + m * r**2) + pt_theta**2 / Jth) / 2)
    tau_th, tau_ph = sp.symbols("tau_theta tau_phi", real=True)
    D = Jphi + m * r**2
    expected = [r * sp.cos(th) * p / D, r * sp.sin(th) * p / D, pt_theta / Jth, p / D, tau_ph, tau_th]  # 3.33
    assert same_matrix(uni_B.rhs, expected)


def test_unicycle_table_3_2_initial_momenta(uni_B):
    P = uni_B.momenta_of_velocity
    on_constraints = {xd: r * sp.cos(th) * phid, yd: r * sp.sin(th) * phid}
    assert same(P[0], (Jphi + m * r**2) * phid, on_constraints)      # p(0) = (J_φ + m r²) φ̇_d(0)
    assert same(P[1], Jth * thd, on_constraints)                     # p̃_θ(0) = J_θ θ̇_d(0)


# ----------------------------------------------------------------------------- snakeboard
def test_snakeboard_lie_algebra_element_3_68(board):
    assert board.symmetry.chosen.fiber == ("x", "y", "theta")
    xi = [2 * r * sp.cos(th) * sp.cos(phi)**2, 2 * r * sp.sin(th) * sp.cos(phi)**2, sp.sin(2 * phi)]
    assert same_matrix(board.steps[3].xi, xi)
    assert board.classification == "mixed"


def test_snakeboard_momentum_3_69_corrected(board):
    # 3.69 prints "J_0 φ̇" in the last term; the correct term is J_r ψ̇
    expected = (2 * m * r * sp.cos(th) * sp.cos(phi)**2 * xd + 2 * m * r * sp.sin(th) * sp.cos(phi)**2 * yd
                + sp.sin(2 * phi) * (m * r**2 * thd + Jr * psid))
    assert same(board.steps[4].p[0], expected, THESIS)


def test_snakeboard_reconstruction_3_71_to_3_73(board):
    assert same_matrix(board.steps[5].Gamma, [1 / (2 * m * r), 0, sp.tan(phi) / (2 * m * r**2)], THESIS)
    assert same_matrix(board.steps[6].e, [2 * r * sp.cos(phi)**2, 0, sp.sin(2 * phi)])
    A = board.steps[5].A   # columns (psi, phi); 3.73 prints φ̇ where ψ̇ multiplies A
    assert same_matrix(A[:, 0], [Jr * sp.sin(phi) * sp.cos(phi) / (m * r), 0,
                                 Jr * sp.sin(phi)**2 / (m * r**2)], THESIS)
    assert same_matrix(A[:, 1], [0, 0, 0])


def test_snakeboard_metric_legendre_and_hamiltonian(board):
    K = board.K
    assert same(K[0, 0], 4 * m * r**2 * sp.cos(phi)**2, THESIS)                     # 3.76
    # 3.75/3.77 print ½J_r − J_r sin²φ/(2mr²) for the ψ̇² coefficient: a factor J_r is missing
    assert same(K[1, 1], Jr * (m * r**2 - Jr * sp.sin(phi)**2) / (m * r**2), THESIS)
    assert same(K[2, 2], 2 * Jw)
    h = (pt_phi**2 / (4 * Jw) + m * r**2 * pt_psi**2 / (Jr * (-Jr + 2 * m * r**2 + Jr * sp.cos(2 * phi)))
         + p**2 / (8 * m * r**2 * sp.cos(phi)**2))                                   # 3.80 (correct)
    assert same(board.hamiltonian, h, THESIS)


def test_snakeboard_table_3_3_initial_momenta(board):
    P = board.momenta_of_velocity
    rest = {xd: 0, yd: 0, thd: 0}
    assert same(P[0], Jr * sp.sin(2 * phi) * psid, {**THESIS, **rest})             # p(0), as printed
    # p̃_ψ(0): the printed 2J_r/(mr²)(mr² − J_r sin²φ)ψ̇ has a spurious factor 2
    assert same(P[1], Jr / (m * r**2) * (m * r**2 - Jr * sp.sin(phi)**2) * psid, {**THESIS, **rest})
    assert same(P[2], 2 * Jw * phid, rest)


def test_snakeboard_structure_matrix_is_skew(board):
    J_ = board.steps[17].J
    assert same_matrix(J_ + J_.T, sp.zeros(*J_.shape))
    Jz = board.structure
    assert Jz.shape == (8, 8)
    assert same_matrix(Jz + Jz.T, sp.zeros(8, 8))


def test_every_step_is_present_and_printable(board):
    assert [s.number for s in board.steps] == list(range(1, 21))
    md = board.steps.to_markdown()
    tex = board.steps.to_latex()
    assert "Step 20" in md
    assert "\\tilde{p}_{\\psi}" in tex
    assert "\\dot{\\theta}" in tex
    assert board.steps[5].label("A") == "A(r)"
    assert board.steps[17].J.shape == (8, 8)
