"""Published values for the Whipple bicycle benchmark (data only; tests/dynamics/test_bicycle.py and
experiments/bench_bicycle.py compare nhgait's bicycle, built from bodies, against them).

* Meijaard, Papadopoulos, Ruina, Schwab, "Linearized dynamics equations for the balance and
  steer of a bicycle: a benchmark and review", Proc. R. Soc. A 463 (2007) 1955–1982, Table 2:
  the eigenvalues of the upright straight motion at 0, 1, …, 10 m/s (as transcribed in
  D. L. Peterson's test of the benchmark, which matches the paper to its 14 decimals), the
  weave and capsize speeds, the weave frequency at the weave speed, and the speed where the two
  real unstable eigenvalues merge into the weave pair with the double eigenvalue there.
* Basu-Mandal, Chatterjee, Papadopoulos, "Hands-free circular motions of a benchmark bicycle",
  Proc. R. Soc. A 463 (2007) 1983–2003, Table 1: a state (their coordinates) and the
  accelerations there, 13–14 digits (as shipped by dtk.bicycle.basu_table_one_input/output).

:func:`basu_mandal_accelerations` evaluates a model at Basu-Mandal's state and converts its
accelerations to their coordinates (through Moore's, as dtk does).
"""
from math import cos, pi, sin

import numpy as np

TABLE2 = {
    0: [-5.53094371765393, -3.13164324790656, 3.13164324790656, 5.53094371765393],
    1: [-7.11008014637442, -3.13423125066578, 3.52696170990070 - 0.80774027519930j,
        3.52696170990070 + 0.80774027519930j],
    2: [-8.67387984831735, -3.07158645641514, 2.68234517512745 - 1.68066296590675j,
        2.68234517512745 + 1.68066296590675j],
    3: [-10.35101467245920, -2.63366137253667, 1.70675605663975 - 2.31582447384325j,
        1.70675605663975 + 2.31582447384325j],
    4: [-12.15861426576450, -1.42944427361326, 0.41325331521125 - 3.07910818603206j,
        0.41325331521125 + 3.07910818603206j],
    5: [-14.07838969279820, -0.77534188219585 - 4.46486771378823j, -0.77534188219585 + 4.46486771378823j,
        -0.32286642900409],
    6: [-16.08537123098030, -1.52644486584142 - 5.87673060598709j, -1.52644486584142 + 5.87673060598709j,
        -0.00406690076970],
    7: [-18.15788466125262, -2.13875644258362 - 7.19525913329805j, -2.13875644258362 + 7.19525913329805j,
        0.10268170574766],
    8: [-20.27940894394569, -2.69348683581097 - 8.46037971396931j, -2.69348683581097 + 8.46037971396931j,
        0.14327879765713],
    9: [-22.43788559040858, -3.21675402252485 - 9.69377351531791j, -3.21675402252485 + 9.69377351531791j,
        0.15790184030917],
    10: [-24.62459635017404, -3.72016840437287 - 10.90681139476287j, -3.72016840437287 + 10.90681139476287j,
         0.16105338653172],
}
WEAVE, CAPSIZE = 4.29238253634111, 6.02426201538837            # Table 2 (a)
WEAVE_FREQUENCY = 3.43503384866144                               # |Im λ| of the weave pair at WEAVE
BIFURCATION, DOUBLE = 0.68428307889246, 3.78290405129320

BASU_STATE = dict(x=0.0, y=0.0, z=0.2440472102925, theta=0.0, psi=0.9501292851472, phi=3.1257073014894,
                  psif=0.2311385135743, betar=0.0, betaf=0.0, xd=-2.8069345714545, yd=-0.1480982396001,
                  zd=0.1058778746261, thetad=0.7830033527065, psid=0.6068425835418, phid=-0.0119185528069,
                  psifd=0.4859824687093, betard=8.9129896614890, betafd=8.0133620584155)
BASU_OUTPUT = dict(xdd=-0.5041626315047, ydd=-0.3449706619454, zdd=-1.4604528332980, thetadd=0.8353281706379,
                   psidd=-7.8555281128244, phidd=0.1205543897884, psifdd=-4.6198904039403,
                   betardd=1.8472554144217, betafdd=2.4548072904550)


def basu_to_moore(b, rr, lam):
    """dtk.bicycle.basu_to_moore_input: Moore's q1 … q8 and u1 … u8 (u = q̇)."""
    st, ct, sp_, cp_ = sin(b["theta"]), cos(b["theta"]), sin(b["psi"]), cos(b["psi"])
    q = [-rr * st * cp_ - b["x"], b["y"] - rr * ct * cp_, -b["theta"], pi / 2 - b["psi"], pi - b["phi"] + lam,
         -b["betar"], -b["psif"], -b["betaf"]]
    u = [rr * b["psid"] * st * sp_ - rr * b["thetad"] * ct * cp_ - b["xd"],
         b["yd"] + rr * b["thetad"] * st * cp_ + rr * b["psid"] * ct * sp_,
         -b["thetad"], -b["psid"], -b["phid"], -b["betard"], -b["psifd"], -b["betafd"]]
    return q, u


def moore_to_basu_accelerations(q, u, up, rr):
    """dtk.bicycle.moore_to_basu: Basu-Mandal's accelerations from Moore's q, u and u̇."""
    s3, c3, s4, c4 = sin(q[2]), cos(q[2]), sin(q[3]), cos(q[3])
    u3, u4 = u[2], u[3]
    return dict(
        xdd=rr * (-s3 * s4 * u3 ** 2 + 2 * c3 * c4 * u3 * u4 + c3 * s4 * up[2] - s3 * s4 * u4 ** 2
                  + s3 * c4 * up[3]) - up[0],
        ydd=up[1] - rr * c3 * s4 * u3 ** 2 - 2 * rr * s3 * c4 * u3 * u4 - rr * s3 * s4 * up[2]
        - rr * c3 * s4 * u4 ** 2
        + rr * c3 * c4 * up[3],
        zdd=-rr * (up[3] * s4 + u4 ** 2 * c4), thetadd=-up[2], psidd=-up[3], phidd=-up[4], betardd=-up[5],
        psifdd=-up[6], betafdd=-up[7])


#: nhgait's whipple_bicycle from Moore's coordinates: x = q1, y = −q2, yaw = −q3, lean = q4,
#: pitch = λ − q5, steer = −q7, rear = −q6, front = −q8 (nhgait: z up, y left, steer left positive)
SIGN = np.array([1, -1, -1, 1, -1, -1, -1, -1])
ORDER = [0, 1, 2, 3, 4, 6, 5, 7]


def basu_mandal_accelerations(model) -> dict:
    """Basu-Mandal's accelerations (their names) computed by ``model`` (nhgait's reduced ODE of
    whipple_bicycle) at their Table 1 state; the state is mapped through ``to_state``, which
    refuses it unless it satisfies the model's constraints (to 1e-8)."""
    from nhgait.dynamics import to_state
    num, system = model.numeric, model.system
    rr, lam = system.parameters["rR"], system.parameters["lam"]
    q_m, u_m = basu_to_moore(BASU_STATE, rr, lam)
    q = SIGN * np.array(q_m)[ORDER] + np.array([0, 0, 0, 0, lam, 0, 0, 0])
    qdot = SIGN * np.array(u_m)[ORDER]
    z = to_state(model, q, qdot)
    qddot = num.call("qddot", 0.0, z, np.zeros(len(system.inputs)), num.params())
    up = np.empty(8)
    up[ORDER] = SIGN * qddot
    return moore_to_basu_accelerations(q_m, u_m, up, rr)
