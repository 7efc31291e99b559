"""Effects on the bearing hinge's interfaces: the bonded fits made frictional contacts.

The modified hinge's rings, pin, clevis and plate are joined either by ties (``bonded``,
the epoxy of the design) or by Coulomb contacts at zero clearance (``contact``, what the
paper's ABAQUS model defined: Sec. IV.B), ``cad.bearing.Interfaces``. With the balls free
to roll (the ``hertz`` ball law carries no tangential force), the bonded model has nothing
that can dissipate: its loop has no area. ``interface_friction`` is the candidate that
asks whether the fits slipping explains measured hysteresis: it turns the bonded model
into the contact one with its own friction coefficient ``mu_interface``.

It changes the structure the cycle runs on (another system: the fits' contact points,
``fe.bearing.fits``), not a condensed operator, so ``apply`` is never reached for a
bearing model: ``model.spec.resolve_structural`` rewrites the model as ``interfaces
= "contact"`` with ``cycle.mu = mu_interface`` before anything is built or looked up, and a
result stored for either spelling serves both. ``mu_interface = 0`` switches the effect
off (the bonded model as it is); any positive value, however small, is the contact model
(a discontinuity the diagnosis sees as a step: frictionless fits are softer than ties).

The fingerprint is measured in ``InterfaceFriction``'s docstring.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from cad.errors import ParameterError
from fe.effects.base import Effect, EffectContext, ParamSpec, Values
from fe.structure.condensed import Condensed


@dataclass(frozen=True)
class InterfaceFriction(Effect):
    """The bearing hinge's bonded interfaces as Coulomb contacts with their own μ.

    MECHANISM: the six fits the paper's ABAQUS model defined as contacts (pin–clevis ×2,
    pin–inner ring ×2, tang bore–outer ring ×2, ``fe.bearing.fits``) stick and slip under
    the reciprocating load; the balls roll without friction (``hertz`` ball law), so these
    fits are the only place the bearing hinge can dissipate.

    FINGERPRINT (μ_interface = 0.2; coarse bearing mesh: size 4, contact 0.8, ring 1.2 mm;
    10 increments per stage; the bonded model vs the effect, both run through
    ``model.service.ModelService``; the slow test in ``tests/fe/bearing/test_interface_friction.py``
    checks every row):

    =======  =====  =======  =========  ==========  ============
    F_p N    Fg N   η base   η effect   δ+ base µm  δ+ effect µm
    =======  =====  =======  =========  ==========  ============
    0        100    0.00001  0.00609    3.24        3.67
    0        400    0.00001  0.00814    9.26        11.00
    200      100    0.00000  0.02055    1.28        1.76
    200      400    0.00000  0.02047    4.84        6.69
    =======  =====  =======  =========  ==========  ============

    η vs amplitude: with the preload the fits' contact pressure is set by F_p, and η is
    nearly independent of Fg (0.0206 / 0.0205); without it the pressure comes from Fg
    itself and η rises with Fg (0.0061 → 0.0081). The secant stiffness falls by 10–40 %
    (the fits slide a little under load); η against μ_interface at F_p = 100 N, 400 N
    rises to ≈ 0.024 near μ = 0.4 and falls beyond (docs/bearing_model.md §5).
    """

    name: str = "interface_friction"
    params: tuple[ParamSpec, ...] = (
        ParamSpec(
            "mu_interface",
            0.0,
            1.0,
            0.2,
            "",
            "Coulomb coefficient of the fits (pin–clevis, pin–inner rings, tang–outer rings)",
        ),
    )
    kinds: tuple[str, ...] = ("bearing",)

    def apply(
        self, configs: Mapping[int, Condensed], values: Values, ctx: EffectContext
    ) -> dict[int, Condensed]:
        """Refuse: the general hinge has no bonded interfaces (the bearing hinge never gets here).

        Raises:
            ParameterError: Always, naming the parameter and its value.
        """
        raise ParameterError(
            f"effects.{self.name}.mu_interface = {values.get('mu_interface', 0.0):g} acts on "
            "the bearing hinge's bonded interfaces (kind = 'bearing'); the general hinge has none"
        )
