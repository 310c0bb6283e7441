"""Scene table ``[mechanism]``: a material that learns a mechanism (kind
``continuum_mechanism``), every key declared with :func:`.keys.key`.

The body is the rectangle ``[0, width] x [0, height]`` at element size ``h`` and its nested
refinements ``h / 2^r``, ``r = 0 .. refine``; the allosteric task and the force inverter are
those of :mod:`continuum_vs_network.continuum.mechanism`.
"""

from typing import Annotated, Literal

from .keys import (
    Float,
    Int,
    _at_least,
    _between,
    _non_negative,
    _positive,
    _unique_nonempty,
    key,
    table,
)

#: Rules of the scene (the package's rule objects learning the modulus field).
MECHANISM_RULES = ("gcl", "exact")
#: Rates: the package's adaptive rate (Adam), or the scaled raw rate (gradient flow).
MECHANISM_RATES = ("adaptive", "scaled")
#: Fields learned beside the modulus: the eigenstrain (rest state), and both together.
MECHANISM_DOFS = ("eigenstrain", "both")


@table
class MechanismSpec:
    """``[mechanism]``: body, task, length scale, rules, rates, references."""

    width: Annotated[Float, _positive] = key(2.0, "body width (length units)")
    height: Annotated[Float, _positive] = key(1.0, "body height (length units)")
    h: Annotated[Float, _positive] = key(0.125, "coarsest element size (length units)")
    refine: Annotated[Int, _between(0, 4)] = key(
        2, "refinements h/2 .. h/2^refine of the learning runs"
    )
    filter_radius: Annotated[Float, _non_negative] = key(
        0.2, "density-filter radius of the modulus field (length units)"
    )
    end_radius: Annotated[Float, _non_negative] = key(
        0.1, "disc radius of the material springs' ends (length units)"
    )
    gap: Annotated[Float, _positive] = key(0.3, "distance between a spring's disc centres")
    source: tuple[Float, ...] = key((0.4, 0.5), "source spring centre (x, y)")
    target: tuple[Float, ...] = key((1.6, 0.5), "target spring centre (x, y)")
    source_strain: Annotated[Float, _positive] = key(0.01, "clamped source strain")
    ratio: Float = key(-0.2, "target strain / source strain asked for")
    rules: Annotated[tuple[Literal[MECHANISM_RULES], ...], _unique_nonempty] = key(
        MECHANISM_RULES, "rules learning the modulus field"
    )
    rates: Annotated[tuple[Literal[MECHANISM_RATES], ...], _unique_nonempty] = key(
        MECHANISM_RATES, "rates: 'adaptive' (Adam), 'scaled' (gradient flow)"
    )
    dofs: Annotated[tuple[Literal[MECHANISM_DOFS], ...], _unique_nonempty] = key(
        MECHANISM_DOFS, "fields learned by GCL beside the modulus (raw rate)"
    )
    dof_refine: Annotated[Int, _between(0, 4)] = key(
        0, "finest refinement of the eigenstrain / both runs"
    )
    dof_alpha: Annotated[Float, _positive] = key(1e7, "raw GCL rate of the eigenstrain / both runs")
    eigenstrain_unit: Annotated[Float, _non_negative] = key(
        0.0,
        "strain unit of the eigenstrain design (sets its susceptibility); 0: balanced, the "
        "first GCL step moves both designs by the same norm on the coarsest mesh",
    )
    adaptive_step: Annotated[Float, _positive] = key(0.2, "step of the adaptive rate")
    scaled_step: Annotated[Float, _positive] = key(0.5, "first step of the scaled rate")
    steps: Annotated[Int, _at_least(1)] = key(200, "learning steps of every run")
    optimum_refine: Annotated[Int, _between(0, 4)] = key(
        0, "finest refinement with an exact optimum (0: the coarsest mesh only)"
    )
    dof_optimum_refine: Annotated[Int, _between(0, 4)] = key(
        0,
        "finest refinement with an exact optimum of the eigenstrain / both fields "
        "(0: the coarsest mesh only; at most dof_refine)",
    )
    volfrac: Annotated[Float, _between(0.01, 1.0)] = key(
        0.5, "SIMP volume fraction (allosteric task)"
    )
    simp_iterations: Annotated[Int, _at_least(1)] = key(100, "SIMP OC iterations")
    inverter_h: Annotated[Float, _positive] = key(
        0.05, "element size of the force inverter (2 x 1 half model)"
    )
    inverter_iterations: Annotated[Int, _at_least(1)] = key(
        100, "OC iterations of the force inverter"
    )
    inverter_radius: Annotated[Float, _positive] = key(
        0.06, "density-filter radius of the inverter"
    )
