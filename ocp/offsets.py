"""State components nothing depends on, pinned at t = 0 so that the NLP has no flat direction.

A state component z_i that the dynamics do not depend on (∂f/∂z_i ≡ 0: a rotor's angle, a
fibre coordinate of a symmetric robot) and that no condition, bound or objective term names by
value — no initial, final or path bound on it or on a derived quantity of it, no state weight;
periodicity z_i(T) = z_i(0) is allowed — enters the problem only through its differences: if
z(t) is a solution, so is z(t) + c e_i for every c. The NLP then has a flat direction, and the
solver's iterates are free to drift along it (a sleigh's rotor angle, free at both ends, ended
at −3.4e14 rad after a warm-started solve, where the re-simulation's round-off alone was 2.4 rad).
:func:`free_offsets` finds such components (structurally, from the sparsity of ∂f/∂z and of the
conditions' expressions); :func:`~nhgait.ocp.conditions.normalise` fixes their initial value at
0, which selects one member of the family and changes nothing else.
"""
from __future__ import annotations

import casadi as ca

__all__ = ["free_offsets"]


def _named_by_value(problem) -> set:
    """Names the statement constrains or weighs by value: the ends' mappings, the path bounds,
    the state weights and the periodic derived quantities (the periodicity of a state is
    invariant under its shift; that of a function of it need not be)."""
    names = set(problem.initial) | set(problem.final) | set(problem.state_bounds) | set(problem.state_weights)
    return names | {name for name in problem.periodic if not problem.is_state(name)}


def free_offsets(problem) -> tuple[str, ...]:
    """The names of the state components of ``problem`` (module docstring) whose value nothing
    depends on, in state order."""
    rhs = problem.model.numeric["rhs"]
    depends = rhs.sparsity_jac(1, 0)            # ∂ż/∂z: rows ż, columns z (the model's states)
    nz = len(problem.model_state_names)         # the integral states that follow start at 0 already
    used = ({j for j in range(nz) if depends.colind()[j + 1] > depends.colind()[j]}
            | set(range(nz, problem.n_states)))
    named = _named_by_value(problem)
    z = ca.SX.sym("z", problem.n_states)
    for name in named:
        if problem.is_state(name):
            used.add(problem.state_names.index(name))
        elif name in problem.derived_quantities:
            inputs = problem.uses_inputs(name)      # a path bound on a quantity of the inputs too
            expr = (problem.quantity(name, z, u=ca.SX.sym("u", problem.n_controls), t=ca.SX.sym("t"))
                    if inputs
                    else problem.quantity(name, z))
            used |= {j for j in range(problem.n_states) if ca.depends_on(expr, z[j])}
    return tuple(name for j, name in enumerate(problem.state_names) if j not in used)
