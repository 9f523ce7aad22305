"""``nhgait derive <scene.toml | built-in> ...``: print the equations of motion (registered by
:mod:`nhgait.gaits.cli`)."""
from __future__ import annotations

import time

__all__ = ["add_derive_parser", "cmd_derive"]


def cmd_derive(args) -> int:
    from nhgait.dynamics import derive
    from nhgait.dynamics.symmetry import symmetry_test
    from nhgait.dynamics.scene import load_scene
    scene = load_scene(args.scene)
    system = scene.system
    forms = ["reduced", "lagrange", "hamilton"] if args.formulation == "all" else [args.formulation]
    for form in forms:
        t0 = time.perf_counter()
        model = derive(system, form, version=args.version, use_cache=not args.no_cache)
        dt = time.perf_counter() - t0
        print(model.to_text())
        print(f"  ({form}: {dt:.3f} s{', no cache' if args.no_cache else ''})\n")
        if form == "reduced":
            if args.table:
                print(model.symmetry.table_markdown() + "\n")
            if args.checks:
                _print_checks(model)
            if args.steps == "markdown":
                print(model.steps.to_markdown(model.symbol_names))
            elif args.steps == "latex":
                print(model.steps.to_latex(model.symbol_names))
    if args.table and "reduced" not in forms:
        print(symmetry_test(system).table_markdown())
    return 0


def _print_checks(model) -> None:
    import sympy as sp
    from nhgait.dynamics import jacobi_test
    res = jacobi_test(model)
    print(f"Jacobi identity of the reduced bracket: {'holds' if res.jacobi_holds else 'fails'} "
          f"(max relative Jacobiator {res.jacobiator:.2g}); constraints "
          f"{'holonomic' if res.holonomic else 'nonholonomic'} (max |ω[X_a, X_b]| {res.holonomy:.2g}); "
          f"thesis §2.2.2 (Jacobi ⇔ holonomic): {'consistent' if res.consistent else 'INCONSISTENT'}")
    print(f"classification (thesis Table 2.1): {model.classification}")
    print("initial-state map (Tables 3.2–3.3), P = Xᵀ M(q) q̇ on ω(q)q̇ = 0:")
    for s, e in zip(model.momenta, model.momenta_of_velocity):
        print(f"  {s} = {sp.sstr(e)}")
    if model.singular_set:
        print("singular set: " + " or ".join(f"{sp.sstr(e)} = 0" for e in model.singular_set))
    print()


def add_derive_parser(subparsers):
    """Add the ``derive`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("derive", help="derive and print the equations of motion")
    p.add_argument("scene", help="scene file (.toml) or built-in name (unicycle, snakeboard, ...)")
    p.add_argument("--formulation", choices=["reduced", "lagrange", "hamilton", "all"], default="reduced")
    p.add_argument("--steps", choices=["latex", "markdown"], help="also print every step of the 20-step method")
    p.add_argument("--table", action="store_true", help="print the full-symmetry-group table (thesis Table 3.1)")
    p.add_argument("--checks", action="store_true",
                   help="Jacobi/holonomy test, Table 2.1 class, the (q, q̇) → state map and the singular set")
    p.add_argument("--version", choices=["A", "B"], help="g = identity (A) or SE(2)-type (B)")
    p.add_argument("--no-cache", action="store_true", help="derive afresh; do not read or write the cache")
    p.set_defaults(func=cmd_derive)
    return p
