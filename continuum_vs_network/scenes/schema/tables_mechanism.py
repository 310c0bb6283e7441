"""Scene table ``[mechanism]``: a material that learns a mechanism (kind
``continuum_mechanism``), every key declared with :func:`.keys._key`.

The body is the rectangle ``[0, width] x [0, height]`` at element size ``h`` and its nested
refinements ``h / 2^r``, ``r = 0 .. refine``; the allosteric task and the force inverter are
those of :mod:`continuum_vs_network.continuum.mechanism`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .keys import _at_least, _between, _key, _non_negative, _positive, _unique_nonempty

#: Rules of the scene (the package's rule objects learning the modulus field).
MECHANISM_RULES = ("gcl", "exact")
#: Rates: the package's adaptive rate (Adam), or the scaled raw rate (gradient flow).
MECHANISM_RATES = ("adaptive", "scaled")
#: Fields learned beside the modulus: the eigenstrain (rest state), and both together.
MECHANISM_DOFS = ("eigenstrain", "both")


@dataclass(frozen=True)
class MechanismSpec:
    """``[mechanism]``: body, task, length scale, rules, rates, references."""

    width: float = _key("float", 2.0, "body width (length units)", check=_positive)
    height: float = _key("float", 1.0, "body height (length units)", check=_positive)
    h: float = _key("float", 0.125, "coarsest element size (length units)", check=_positive)
    refine: int = _key(
        "int", 2, "refinements h/2 .. h/2^refine of the learning runs", check=_between(0, 4)
    )
    filter_radius: float = _key(
        "float",
        0.2,
        "density-filter radius of the modulus field (length units)",
        check=_non_negative,
    )
    end_radius: float = _key(
        "float",
        0.1,
        "disc radius of the material springs' ends (length units)",
        check=_non_negative,
    )
    gap: float = _key("float", 0.3, "distance between a spring's disc centres", check=_positive)
    source: tuple[float, ...] = _key("list[float]", (0.4, 0.5), "source spring centre (x, y)")
    target: tuple[float, ...] = _key("list[float]", (1.6, 0.5), "target spring centre (x, y)")
    source_strain: float = _key("float", 0.01, "clamped source strain", check=_positive)
    ratio: float = _key("float", -0.2, "target strain / source strain asked for")
    rules: tuple[str, ...] = _key(
        "list[str]", MECHANISM_RULES, "rules learning the modulus field",
        choices=MECHANISM_RULES, check=_unique_nonempty,
    )  # fmt: skip
    rates: tuple[str, ...] = _key(
        "list[str]", MECHANISM_RATES, "rates: 'adaptive' (Adam), 'scaled' (gradient flow)",
        choices=MECHANISM_RATES, check=_unique_nonempty,
    )  # fmt: skip
    dofs: tuple[str, ...] = _key(
        "list[str]", MECHANISM_DOFS, "fields learned by GCL beside the modulus (raw rate)",
        choices=MECHANISM_DOFS, check=_unique_nonempty,
    )  # fmt: skip
    dof_refine: int = _key(
        "int", 0, "finest refinement of the eigenstrain / both runs", check=_between(0, 4)
    )
    dof_alpha: float = _key(
        "float", 1e7, "raw GCL rate of the eigenstrain / both runs", check=_positive
    )
    eigenstrain_unit: float = _key(
        "float", 0.0,
        "strain unit of the eigenstrain design (sets its susceptibility); 0: balanced, the "
        "first GCL step moves both designs by the same norm on the coarsest mesh",
        check=_non_negative,
    )  # fmt: skip
    adaptive_step: float = _key("float", 0.2, "step of the adaptive rate", check=_positive)
    scaled_step: float = _key("float", 0.5, "first step of the scaled rate", check=_positive)
    steps: int = _key("int", 200, "learning steps of every run", check=_at_least(1))
    optimum_refine: int = _key(
        "int",
        0,
        "finest refinement with an exact optimum (0: the coarsest mesh only)",
        check=_between(0, 4),
    )
    dof_optimum_refine: int = _key(
        "int",
        0,
        "finest refinement with an exact optimum of the eigenstrain / both fields "
        "(0: the coarsest mesh only; at most dof_refine)",
        check=_between(0, 4),
    )
    volfrac: float = _key(
        "float", 0.5, "SIMP volume fraction (allosteric task)", check=_between(0.01, 1.0)
    )
    simp_iterations: int = _key("int", 100, "SIMP OC iterations", check=_at_least(1))
    inverter_h: float = _key(
        "float", 0.05, "element size of the force inverter (2 x 1 half model)", check=_positive
    )
    inverter_iterations: int = _key(
        "int", 100, "OC iterations of the force inverter", check=_at_least(1)
    )
    inverter_radius: float = _key(
        "float", 0.06, "density-filter radius of the inverter", check=_positive
    )
