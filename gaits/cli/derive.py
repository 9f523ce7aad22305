"""``nhgait derive <scene.toml | built-in> ...``: print the equations of motion (registered by
:mod:`nhgait.gaits.cli.main`). No symbolic work here: the models print themselves, and the
text a cached model printed is cached with it (:func:`model_text`): a warm ``derive`` prints
from the cache, without sympy's ``factor`` for display."""
from __future__ import annotations

import time

__all__ = ["add_derive_parser", "cmd_derive", "model_text"]


def cmd_derive(args) -> int:
    from nhgait.dynamics import FORMULATIONS, derive
    from nhgait.dynamics.derivation.input.scene import load_scene
    from nhgait.dynamics.derivation.symmetry import symmetry_test
    scene = load_scene(args.scene)
    system = scene.system
    if scene.urdf is not None:                 # show what was generated from the URDF
        print(scene.urdf.to_text() + "\n")
    forms = list(FORMULATIONS) if args.formulation == "all" else [args.formulation]
    for form in forms:
        t0 = time.perf_counter()
        model = derive(system, form, version=args.version, use_cache=not args.no_cache)
        dt = time.perf_counter() - t0
        print(model_text(model, args.cse, use_cache=not args.no_cache))
        print(f"  ({form}: {dt:.3f} s{', no cache' if args.no_cache else ''})\n")
        if form == "reduced":
            if args.table:
                print(model.symmetry.table_markdown() + "\n")
            if args.checks:
                print(model.checks_text())
            if args.reconstruction:
                from nhgait.dynamics.geometry import reconstruction
                print(reconstruction(model).to_text() + "\n")
            if args.steps == "markdown":
                print(model.steps.to_markdown())
            elif args.steps == "latex":
                print(model.steps.to_latex())
    if args.reconstruction and "reduced" not in forms:
        from nhgait.dynamics.geometry import reconstruction
        print(reconstruction(derive(system, "reduced", version=args.version,
                                    use_cache=not args.no_cache)).to_text() + "\n")
    if args.table and "reduced" not in forms:
        print(symmetry_test(system).table_markdown())
    return 0


#: the cache entries of the printed equations end with this
TEXT_SUFFIX = ".text.pkl"


def model_text(model, cse=None, *, use_cache: bool = True) -> str:
    """``model.to_text(cse=cse)``, read from the cache when this model came from it and printed
    before: the entry's key is the model's own cache key (its structure, the code and the
    versions: :class:`~nhgait.dynamics.numerics.cache.Provenance`) with the system's name and
    ``cse``; the text is stored the first time (nothing is stored for a model derived without
    the cache)."""
    provenance = getattr(model, "provenance", None)
    if not use_cache or provenance is None:
        return model.to_text(cse=cse)
    from nhgait.dynamics.numerics import cache
    key = cache.make_key("printed equations", provenance.key, model.system.name, repr(cse))
    text = cache.load(key, str, suffix=TEXT_SUFFIX)
    if text is None:
        text = model.to_text(cse=cse)
        cache.store(key, text, suffix=TEXT_SUFFIX)
    return text


def add_derive_parser(subparsers):
    """Add the ``derive`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("derive", help="derive and print the equations of motion")
    p.add_argument("scene", help="scene file (.toml) or built-in name (unicycle, snakeboard, ...)")
    p.add_argument("--formulation", choices=["reduced", "lagrange", "hamilton", "all"], default="reduced")
    p.add_argument("--steps", choices=["latex", "markdown"],
                   help="also print every step of the 20-step method")
    p.add_argument("--table", action="store_true",
                   help="print the full-symmetry-group table (thesis Table 3.1)")
    p.add_argument("--checks", action="store_true",
                   help="Jacobi/holonomy test, Table 2.1 class, the (q, q̇) → state map and the singular set")
    p.add_argument("--reconstruction", action="store_true",
                   help="the reconstruction equation ξ = −A(r)ṙ + Γ(r)pᵀ of the chosen fibre, its thesis "
                        "Table 2.1 type and (mixed systems) the momentum equation")
    p.add_argument("--version", choices=["A", "B"], help="g = identity (A) or SE(2)-type (B)")
    cse = p.add_mutually_exclusive_group()
    cse.add_argument("--cse", dest="cse", action="store_true", default=None,
                     help="name repeated sub-expressions once (w1 = …; the default for long equations)")
    cse.add_argument("--no-cse", dest="cse", action="store_false", help="print every equation in full")
    p.add_argument("--no-cache", action="store_true", help="derive afresh; do not read or write the cache")
    p.set_defaults(func=cmd_derive)
    return p
