"""Where a plan's system and task come from: scene files, the built-in task library, overrides.

The built-in gait tasks are data, in the same ``[task]`` format a user writes
(``gaits/library/<scene>.toml``: ``scene = "<built-in scene>"``, optional ``[units]`` and
``[drawing]`` for the plots, and one ``[tasks.<name>]`` table per task):

* unicycle ``parallel-park`` (P1), snakeboard ``forward`` (P2), ``rotate`` (P3), ``lateral`` (P4).

:func:`resolve` turns what the user gave — a scene (file, built-in name, :class:`Scene` or
:class:`System`), a task (None for the scene's own ``[task]``, a gait name of the library, a
``[task]`` dict or a :class:`~nhgait.gaits.tasks.statement.Task`) and ``--set`` overrides — into one
:class:`Plan`: the scene and the parsed task. Built-ins and users share this one path.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from typing import Any, NamedTuple

from nhgait.dynamics.suggestions import did_you_mean
from nhgait.ocp import ProblemError

from .statement import Task, apply_overrides, parse_task

__all__ = ["Plan", "resolve", "scene_of", "library", "library_tasks", "library_task_names", "get_task",
           "FigureTables", "figure_tables"]

LIBRARY_KEYS = {"scene", "units", "drawing", "tasks"}


@dataclass(frozen=True, eq=False)
class Plan:
    """A system and a task to plan.

    Attributes
    ----------
    scene : the :class:`~nhgait.dynamics.derivation.input.scene.Scene` (system, quantities, units, drawing).
    task : the parsed :class:`~nhgait.gaits.tasks.statement.Task`.
    label : "<system>/<task>" for reports and file headers.
    units, drawing : the scene's tables merged over the library's (for built-ins).
    """

    scene: Any
    task: Task
    label: str
    units: Mapping = field(default_factory=dict)
    drawing: Mapping | None = None

    @property
    def system(self):
        return self.scene.system


def library(scene_name: str) -> dict | None:
    """The library entry of a built-in scene (dict with scene, units, drawing, tasks) or None."""
    name = str(scene_name).replace("-", "_")
    try:
        text = resources.files("nhgait.gaits").joinpath("library", f"{name}.toml").read_text()
    except (FileNotFoundError, OSError):
        return None
    from nhgait.dynamics.derivation.input.tomldata import read_toml
    data = read_toml(text, f"built-in task library {name}", ProblemError)
    unknown = set(data) - LIBRARY_KEYS
    tasks = data.get("tasks", {})
    if unknown or not isinstance(tasks, dict):  # pragma: no cover - guards the shipped data
        raise ProblemError([f"unknown key(s) {sorted(unknown)} or bad [tasks]"],
                           title=f"invalid library {name}")
    return data


def _library_names() -> list:
    folder = resources.files("nhgait.gaits").joinpath("library")
    return sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".toml"))


def library_tasks() -> dict:
    """(scene, task name) → the raw ``[tasks.<name>]`` table, for every built-in task."""
    out = {}
    for name in _library_names():
        for task_name, table in library(name).get("tasks", {}).items():
            out[(name, task_name)] = table
    return out


def library_task_names() -> tuple[str, ...]:
    """(scene, task name) of every built-in task, sorted (the library files read now)."""
    return tuple(sorted(library_tasks()))


def get_task(scene_name: str, name: str) -> Task:
    """The built-in task ``name`` of ``scene_name`` (ProblemError listing the known ones)."""
    data = library(scene_name)
    tasks = (data or {}).get("tasks", {})
    if name not in tasks:
        tasks = library_task_names()
        here = [n for s, n in tasks if s == scene_name] or [n for _, n in tasks]
        known = ", ".join(f"{s} {n}" for s, n in tasks)
        hint = did_you_mean(name, here)
        raise ProblemError([f"unknown gait {name!r} for system {scene_name!r}{': ' + hint if hint else ''} "
                            f"(known: {known}; a scene file plans its own [task])"],
                           title="invalid gait task")
    return parse_task({"name": name, **tasks[name]}, where=f"[tasks.{name}]")


def _load_scene(system):
    from nhgait.dynamics.derivation.input.scene import Scene, load_scene
    from nhgait.dynamics.derivation.system import System
    if isinstance(system, Scene):
        return system
    if isinstance(system, System):
        return Scene(system=system, simulation=None, source=system.name)
    return load_scene(system)


def _scene_name(scene) -> str:
    source = str(scene.source)
    if source.startswith("built-in scene "):
        return source[len("built-in scene "):]
    return scene.system.name


class FigureTables(NamedTuple):
    """A scene's ``[units]`` and ``[drawing]`` for its figures."""

    units: dict
    drawing: Mapping | None


def figure_tables(scene, lib: dict | None = None) -> FigureTables:
    """The scene's ``[units]`` over its built-in library's, and its ``[drawing]``, else the
    library's: ``nhgait simulate --plot`` and ``nhgait plan`` draw the same body. ``lib``: the
    library entry when already read (None: read for a built-in scene)."""
    if lib is None and str(scene.source).startswith("built-in scene "):
        lib = library(_scene_name(scene))
    units = {**((lib or {}).get("units", {})), **dict(scene.units or {})}
    drawing = scene.drawing if scene.drawing is not None else (lib or {}).get("drawing")
    return FigureTables(units, drawing)


class NamedScene(NamedTuple):
    """What :func:`scene_of` returns."""

    scene: Any   #: the Scene
    name: str    #: the built-in's name, else the system's


def scene_of(system) -> NamedScene:
    """(the Scene of ``system`` — a scene file path, built-in scene name, Scene or System —, its
    name: the built-in's, else the system's), read before any task."""
    scene = _load_scene(system)
    return NamedScene(scene, _scene_name(scene))


def resolve(system, task=None, *, overrides=()) -> Plan:
    """The :class:`Plan` for ``system`` and ``task`` (see the module docstring).

    Parameters
    ----------
    system : scene file path, built-in scene name, Scene or System
    task : None (the scene's ``[task]``), a library gait name (str), a ``[task]`` dict or a Task
    overrides : ``key.sub=value`` strings applied to the task table (``nhgait plan --set``)
    """
    scene, name = scene_of(system)
    lib = library(name) if str(scene.source).startswith("built-in scene ") else None
    units, drawing = figure_tables(scene, lib)
    check = {"system": scene.system, "quantities": scene.all_quantities,
             "motion": tuple(scene.motion_quantities)}
    if isinstance(task, Task):
        task = parse_task(apply_overrides(task.to_dict(), overrides), **check)
        return Plan(scene, task, f"{name}/{task.name}", units, drawing)
    if isinstance(task, str):
        if lib is None:
            raise ProblemError([f"--gait {task}: the built-in gaits belong to the built-in scenes, and "
                                f"{scene.source} is a scene file: plan its own [task] (without "
                                "--gait), or the built-in scene by name (nhgait plan snakeboard "
                                "--gait forward)"],
                               title="unknown gait")
        tasks = lib.get("tasks", {})
        if task not in tasks:
            get_task(name, task)      # raises with the list of known gaits
        table, where = {"name": task, **tasks[task]}, f"[tasks.{task}]"
    elif task is None:
        if scene.task is None:
            known = [n for s, n in library_task_names() if s == name] if lib is not None else []
            hint = (f" or choose a built-in gait with --gait ({', '.join(known)})" if known else "")
            raise ProblemError([f"{scene.source} has no [task] table: add one (docs/gait-planning.md){hint}"],
                               title="nothing to plan")
        table, where = {"name": "task", **scene.task}, "[task]"
    elif isinstance(task, Mapping):
        table, where = {"name": "task", **task}, "[task]"
    else:
        raise ProblemError([f"task must be a gait name, a [task] table or a Task, got {type(task).__name__}"],
                           title="invalid task")
    parsed = parse_task(apply_overrides(table, overrides), where=where, **check)
    return Plan(scene, parsed, f"{name}/{parsed.name}", units, drawing)


def describe_library() -> str:
    """One line per built-in task (for ``--help``)."""
    lines = []
    for (scene, name), table in library_tasks().items():
        lines.append(f"{scene} {name}: {table.get('description', '')}")
    return "\n".join(lines)

