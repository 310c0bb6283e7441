"""What each kind checks that its model's types cannot say: which builders and tasks it
runs on, the keys it needs, and the combinations of keys it refuses
(:attr:`.kinds.Kind.check`). Each raises :class:`SceneError` naming the table and key."""

from typing import Any

from .keys import (
    BEYOND_RULES,
    CONTINUUM_RULES,
    PAPER_RULES,
    PAPER_SETTING_RULES,
    RULES,
    STERN_RULES,
)
from .values import SceneError


def _need_key(scene: Any, file: str, table: str, key: str, why: str) -> None:
    value = getattr(getattr(scene, table), key)
    if value is None or value == ():
        raise SceneError(file, table, key, f"is required {why}")


def _triangular(scene: Any, file: str, message: str) -> None:
    if scene.network.builder != "triangular":
        raise SceneError(file, "network", "builder", message)


def _task_kind(scene: Any, file: str, kind: str, message: str) -> None:
    if scene.task is not None and scene.task.kind != kind:
        raise SceneError(file, "task", "kind", message)


def _rules_in(scene: Any, file: str, allowed: tuple, message: str) -> None:
    bad = [r for r in scene.learning.rules if r not in allowed]
    if bad:
        raise SceneError(file, "learning", "rules", f"{bad[0]!r} {message} ({', '.join(allowed)})")


def _initial(scene: Any, file: str, why: str) -> None:
    if scene.learning.strain_reference != "initial":
        raise SceneError(file, "learning", "strain_reference", why)


def nothing(scene: Any, file: str) -> None:
    """A kind whose model says everything."""


def lattice(scene: Any, file: str) -> None:
    """transmission and solvers (and the start of relaxation and stability): lattices of
    the sizes given, a source task."""
    kind = scene.kind
    _triangular(scene, file, f"kind {kind!r} runs on triangular lattices ('triangular')")
    _task_kind(scene, file, "source", f"kind {kind!r} takes kind = 'source'")
    if kind != "stability":
        _need_key(scene, file, "network", "sizes", f"for a {kind} scene")


def relaxation(scene: Any, file: str) -> None:
    lattice(scene, file)
    if scene.continuum is not None and scene.dynamics.scheme == "explicit":
        raise SceneError(
            file,
            "dynamics",
            "scheme",
            "the continuum has no explicit scheme; use 'implicit' or 'newmark'",
        )


def stability(scene: Any, file: str) -> None:
    lattice(scene, file)
    _need_key(scene, file, "network", "size", "for a stability scene")
    if not (scene.network.stiffness_ratios or scene.task.strains or scene.solver.rod_stiffnesses):
        raise SceneError(
            file,
            "network",
            "stiffness_ratios",
            "a stability scene needs cases: stiffness_ratios, "
            "[task] strains or [solver] rod_stiffnesses",
        )


def allostery(scene: Any, file: str) -> None:
    a = scene.allostery
    if a.alpha is not None and a.step is not None:
        raise SceneError(
            file, "allostery", "step", "a raw rate alpha has no step; set one of the two"
        )


def physical_time(scene: Any, file: str) -> None:
    net, spec = scene.network, scene.physical_time
    _triangular(scene, file, "kind 'physical_time' runs on triangular lattices")
    _need_key(scene, file, "network", "sizes", "for a physical_time scene")
    _task_kind(scene, file, "stern", "kind 'physical_time' takes kind = 'stern'")
    if len(spec.draws) not in (1, len(net.sizes)):
        raise SceneError(
            file,
            "physical_time",
            "draws",
            f"must give one number for every size or one per size ({len(net.sizes)} sizes), "
            f"got {len(spec.draws)}",
        )
    if (spec.arm_stiffness > 0) != (spec.arm_dashpot > 0):
        raise SceneError(
            file,
            "physical_time",
            "arm_dashpot",
            "arm_stiffness and arm_dashpot must both be > 0 (a Maxwell arm) or both 0",
        )


def continuum_learning(scene: Any, file: str) -> None:
    _triangular(scene, file, "continuum_learning runs on a triangular lattice")
    _need_key(scene, file, "network", "size", "for a continuum_learning scene (an n x n lattice)")
    _task_kind(scene, file, "stern", "continuum_learning takes kind = 'stern'")
    _rules_in(scene, file, CONTINUUM_RULES, "is not a continuum_learning rule")
    _initial(
        scene,
        file,
        "a continuum's material springs measure strain against the undeformed body; "
        "set strain_reference = 'initial'",
    )


def beyond_paper(scene: Any, file: str) -> None:
    _triangular(scene, file, "beyond_paper runs on triangular lattices")
    _need_key(
        scene, file, "network", "sizes", "for a beyond_paper scene (the capacity study's lattices)"
    )
    _task_kind(
        scene, file, "stern", "beyond_paper takes kind = 'stern' (the paper's task is added)"
    )
    _rules_in(scene, file, BEYOND_RULES, "is not a beyond_paper rule")
    _initial(
        scene, file, "beyond_paper learns fixed target geometries; set strain_reference = 'initial'"
    )


def learning(scene: Any, file: str) -> None:
    net, L = scene.network, scene.learning
    if net.builder == "paper":
        _task_kind(scene, file, "paper", "the paper network takes the paper task (kind = 'paper')")
        _paper_rules(L, file)
    else:
        _task_kind(scene, file, "stern", f"a {net.builder!r} network takes kind = 'stern'")
        _need_key(scene, file, "network", "n_nodes", "for a learning scene on a large network")
        _initial(
            scene,
            file,
            "Stern-scale runs measure strains against the initial rest "
            "lengths; set strain_reference = 'initial'",
        )
        bad = [r for r in L.rules if r in PAPER_RULES]
        if bad:
            raise SceneError(
                file,
                "learning",
                "rules",
                f"{bad[0]!r} exists for the paper task only (Stern-scale 'gcl', 'gpc' "
                "and 'exact' already freeze sources and targets; 'gcl_all' and "
                "'gpc_all' let every spring learn)",
            )
    if scene.solver is not None:
        bad = [m for m in scene.solver.methods if m not in ("newton", "paper")]
        if bad:
            raise SceneError(
                file,
                "solver",
                "methods",
                f"learning runs use 'newton' (exact equilibria) or 'paper' "
                f"(the paper's Adagrad), got {bad[0]!r}",
            )
    if scene.export is not None:
        bad = [t for t in scene.export.trials if t >= L.trials]
        if bad:
            raise SceneError(
                file,
                "export",
                "trials",
                f"trial {bad[0]} does not exist ([learning] trials = {L.trials})",
            )


def _paper_rules(L: Any, file: str) -> None:
    """The rules of a learning scene on the paper's task."""
    allowed = PAPER_SETTING_RULES if L.paper_setting else RULES
    bad = [r for r in L.rules if r not in allowed or (r == "gcl_notebook" and not L.paper_setting)]
    if bad and bad[0] not in STERN_RULES:
        raise SceneError(
            file,
            "learning",
            "rules",
            f"{bad[0]!r} is not a run of "
            + (
                "the paper's own setting (paper_setting = true runs "
                + ", ".join(PAPER_SETTING_RULES)
                + ")"
                if L.paper_setting
                else "the package's setting ('gcl_notebook' needs paper_setting = true)"
            ),
        )
    bad = [r for r in L.rules if r in STERN_RULES]
    if bad:
        raise SceneError(
            file,
            "learning",
            "rules",
            f"{bad[0]!r} exists for Stern-scale tasks only (the paper's 'gcl' and "
            "'gpc' already let every spring learn; directed aging of the paper task "
            "is in the beyond_paper scene)",
        )
