"""The NLP solvers nhgait drives, one object each: :data:`IPOPT` and :data:`FATROP`.

``SolverOptions.solver`` (a name, checked against :data:`BACKENDS`) is resolved once into one
of these objects (``SolverOptions.backend``); the solver machinery asks it what differs between
the two instead of comparing the name:

* Ipopt (interior point, general sparse KKT systems through MUMPS): a limited-memory Hessian,
  its own wall-time limit (``max_wall_time``), an iteration callback (progress lines, the
  deadline), ``stats["success"]`` trusted;
* FATROP (interior point on the stage structure, Riccati recursion): needs the stage-ordered
  transcription and its dimensions (``structure_detection = "manual"``), no time option (its
  attempts are bounded by their supervisor), convergence read from its return flag.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SolverBackend", "IPOPT", "FATROP", "BACKENDS"]


@dataclass(frozen=True)
class SolverBackend:
    """What one NLP solver offers.

    Attributes
    ----------
    name : CasADi's plugin name (``SolverOptions.solver``).
    label : the name in messages.
    limited_memory : offers a limited-memory (L-BFGS) Hessian.
    time_option : honours ``time_limit`` itself.
    iteration_callback : calls an iteration callback (progress lines, a deadline).
    stage_structure : needs the stage-ordered transcription and its dimensions.
    mumps : factorises its KKT matrix with MUMPS (the collocation scaling applies).
    reports_success : ``stats["success"]`` says whether it converged (else read from its own
        measures).
    """

    name: str
    label: str
    limited_memory: bool
    time_option: bool
    iteration_callback: bool
    stage_structure: bool
    mumps: bool
    reports_success: bool

    def own_options(self, options) -> dict:
        """The solver's own extra options of ``options`` (a ``SolverOptions``)."""
        return dict(getattr(options, self.name))

    def nlpsol_options(self, options, opts: dict) -> dict:
        """``opts`` with this solver's settings from ``options``."""
        raise NotImplementedError

    def verbose_options(self, opts: dict) -> dict:
        """``opts`` with the solver's own log switched on."""
        raise NotImplementedError

    def structure_options(self, nlp, opts: dict) -> dict:
        """``opts`` with the stage dimensions of ``nlp`` when the solver needs them."""
        if not self.stage_structure:
            return opts
        st = nlp.structure
        return {**opts, "structure_detection": "manual", "N": st["N"], "nx": st["nx"], "nu": st["nu"],
                "ng": st["ng"]}


#: Ipopt's largest unscaled constraint violation of a point it stops at as "acceptable" (its own
#: default, 1e-2, let a generated 3-link chain's gait stop 2e-5 off its end conditions: a
#: converged status that the re-simulation, at 1e-6, then refuses — solving again with more RK4
#: sub-steps cannot mend an NLP point that does not meet its own constraints)
ACCEPTABLE_CONSTR_VIOL = 1e-8


@dataclass(frozen=True)
class IpoptBackend(SolverBackend):
    """Ipopt: its options are ``ipopt.``-prefixed keys of the nlpsol options. ``no_nlp_grad``:
    CasADi's gradient of the Lagrangian serves only ``lam_p`` (the NLPs have no p; Ipopt gives
    ``lam_x``); generated, its reverse sweep through the stage was 36 % of the 8-link snake's C
    (issue 25). FATROP's interface calls it."""

    def nlpsol_options(self, options, opts: dict) -> dict:
        hessian = "limited-memory" if options.hessian == "limited-memory" else "exact"
        opts = {**opts, "ipopt.print_level": options.print_level, "ipopt.sb": "yes",
                "ipopt.max_iter": int(options.max_iter), "ipopt.tol": float(options.tol),
                "ipopt.hessian_approximation": hessian, "ipopt.linear_solver": options.linear_solver,
                "ipopt.acceptable_constr_viol_tol": ACCEPTABLE_CONSTR_VIOL, "no_nlp_grad": True}
        if options.time_limit is not None:
            opts["ipopt.max_wall_time"] = float(options.time_limit)
        opts.update({f"ipopt.{k}" if not k.startswith("ipopt.") else k: v for k, v in options.ipopt.items()})
        return opts

    def verbose_options(self, opts: dict) -> dict:
        return {**opts, "ipopt.print_level": 5}


@dataclass(frozen=True)
class FatropBackend(SolverBackend):
    """FATROP: its options are one ``fatrop`` dictionary of the nlpsol options."""

    def nlpsol_options(self, options, opts: dict) -> dict:
        fopts = {"print_level": options.print_level, "max_iter": int(options.max_iter),
                 "tol": float(options.tol)}
        fopts.update(options.fatrop)
        return {**opts, "fatrop": fopts}

    def verbose_options(self, opts: dict) -> dict:
        return {**opts, "fatrop": {**opts.get("fatrop", {}), "print_level": 10}}


IPOPT = IpoptBackend(name="ipopt", label="Ipopt", limited_memory=True, time_option=True,
                     iteration_callback=True, stage_structure=False, mumps=True, reports_success=True)
FATROP = FatropBackend(name="fatrop", label="FATROP", limited_memory=False, time_option=False,
                       iteration_callback=False, stage_structure=True, mumps=False, reports_success=False)

#: solver name → its back end
BACKENDS = {backend.name: backend for backend in (IPOPT, FATROP)}
