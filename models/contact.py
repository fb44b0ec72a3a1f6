"""Contact materials and the plant's contact configuration.

Hydroelastic contact everywhere it matters: the hand's links and sensor pads, the movable
object and the obstacles are *compliant* hydroelastic (they have a pressure field), the
table is *rigid* hydroelastic. Pairs that cannot be resolved hydroelastically (the arm's
links, which carry no hydroelastic properties, or rigid-rigid pairs) fall back to point
contact: ``contact_model = "hydroelastic_with_fallback"``.

The discrete time step and contact approximation are parameters of :class:`SimulationConfig`;
the default step was chosen by measurement (``cmanip bench timestep``,
``experiments/timestep_bench.py``): see the comment on :data:`DEFAULT_TIME_STEP_S`.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    ProximityProperties,
)
from pydrake.multibody.plant import CoulombFriction, MultibodyPlantConfig

from models.config import Fields

#: Discrete time step (s), chosen by ``cmanip bench timestep`` (demo push, box 0.3 m at
#: 5 cm/s; baseline 1 ms; measured 2026-11-22 on the 2-core CI machine):
#:
#:   step  real-time factor  box final pose vs 1 ms   patch force RMS vs 1 ms
#:   1 ms  0.58              -                        -
#:   2 ms  1.22              0.0 mm, 0.00 deg         0.002 N
#:   5 ms  1.90              0.1 mm, 0.01 deg         0.007 N
#:   10 ms 4.11              0.2 mm, 0.02 deg         0.014 N
#:   20 ms 5.24              0.3 mm, 0.02 deg         0.027 N
#:
#: Every step up to 20 ms reproduces this slow, quasi-static push. We take 5 ms: faster
#: than real time with a margin of 4x below the steps whose force error approaches the
#: sensor noise (0.05 N), for stiffer objects (seed 003's steel, 1e8 Pa) and faster pushes.
DEFAULT_TIME_STEP_S = 0.005


@dataclass(frozen=True)
class ContactMaterial:
    """Contact properties of one geometry.

    Attributes:
        hydroelastic_modulus_pa: compliant hydroelastic modulus (Pa); ``None`` makes the
            geometry rigid hydroelastic.
        mu_static: static Coulomb friction coefficient (dimensionless, >= mu_dynamic).
        mu_dynamic: dynamic Coulomb friction coefficient (dimensionless).
        dissipation_s_per_m: Hunt-Crossley dissipation (s/m), used by the lagged/similar
            discrete approximations.
        relaxation_time_s: linear Kelvin-Voigt relaxation time (s), used by SAP.
        resolution_hint_m: edge length (m) of the pressure-field tessellation of curved
            shapes (cylinders, spheres); ignored by boxes and convex meshes.
    """

    hydroelastic_modulus_pa: float | None = 1.0e6
    mu_static: float = 0.5
    mu_dynamic: float = 0.5
    dissipation_s_per_m: float = 5.0
    relaxation_time_s: float = 0.01
    resolution_hint_m: float = 0.01

    def proximity_properties(self) -> ProximityProperties:
        """The Drake ``ProximityProperties`` for a collision geometry of this material."""
        props = ProximityProperties()
        AddContactMaterial(
            dissipation=self.dissipation_s_per_m,
            point_stiffness=None,
            friction=CoulombFriction(self.mu_static, self.mu_dynamic),
            properties=props,
        )
        props.AddProperty("material", "relaxation_time", self.relaxation_time_s)
        if self.hydroelastic_modulus_pa is None:
            AddRigidHydroelasticProperties(self.resolution_hint_m, props)
        else:
            AddCompliantHydroelasticProperties(
                self.resolution_hint_m, self.hydroelastic_modulus_pa, props
            )
        return props

    @staticmethod
    def from_fields(fields: Fields, default: ContactMaterial) -> ContactMaterial:
        """Read a ``contact`` section: overrides on top of ``default``.

        Every field is optional, by design: a body without overrides is made of its
        ``default`` material (the material constants below). The fields:

        - ``rigid: true`` (rigid hydroelastic) or ``hydroelastic_modulus_pa`` (Pa, compliant),
          not both; with neither, the default's compliance (and modulus) is kept.
          ``rigid: false`` over a rigid default needs a modulus.
        - ``mu_static`` and ``mu_dynamic`` (dimensionless), together or not at all (with
          one only, the other would silently stay the default's).

        Dissipation, relaxation time and resolution hint always come from ``default``.

        Raises:
            ConfigError: naming the file and field of a missing, malformed or contradictory
                entry.
        """
        rigid = fields.boolean("rigid", default.hydroelastic_modulus_pa is None)
        if rigid:
            if fields.has("hydroelastic_modulus_pa"):
                raise fields.error("hydroelastic_modulus_pa",
                                   "a rigid material has no modulus (remove one of the two)")
            modulus = None
        elif default.hydroelastic_modulus_pa is None:
            modulus = fields.number("hydroelastic_modulus_pa", min=1e3, max=1e12)
        else:
            modulus = fields.number("hydroelastic_modulus_pa", default.hydroelastic_modulus_pa,
                                    min=1e3, max=1e12)
        if fields.has("mu_static") or fields.has("mu_dynamic"):
            mu_dynamic = fields.number("mu_dynamic", min=0.0, max=5.0)
            mu_static = fields.number("mu_static", min=0.0, max=5.0)
        else:
            mu_dynamic, mu_static = default.mu_dynamic, default.mu_static
        if mu_static < mu_dynamic:
            raise fields.error("mu_static", f"{mu_static} must be >= mu_dynamic ({mu_dynamic})")
        fields.done()
        return ContactMaterial(
            hydroelastic_modulus_pa=modulus,
            mu_static=mu_static,
            mu_dynamic=mu_dynamic,
            dissipation_s_per_m=default.dissipation_s_per_m,
            relaxation_time_s=default.relaxation_time_s,
            resolution_hint_m=default.resolution_hint_m,
        )


#: Rubber-like sensor pads and finger links of the hand.
HAND_MATERIAL = ContactMaterial(hydroelastic_modulus_pa=5.0e5, mu_static=0.5, mu_dynamic=0.5)
#: Default for movable objects (hard plastic / cardboard-like).
OBJECT_MATERIAL = ContactMaterial(hydroelastic_modulus_pa=2.0e6, mu_static=0.4, mu_dynamic=0.4)
#: Obstacles on the table.
OBSTACLE_MATERIAL = ContactMaterial(hydroelastic_modulus_pa=5.0e6, mu_static=0.5, mu_dynamic=0.5)
#: The table top: rigid hydroelastic.
TABLE_MATERIAL = ContactMaterial(hydroelastic_modulus_pa=None, mu_static=0.3, mu_dynamic=0.3)


@dataclass(frozen=True)
class SimulationConfig:
    """How the world is simulated.

    Attributes:
        time_step_s: discrete plant step (s).
        contact_approximation: Drake discrete contact approximation; one of
            ``"sap"``, ``"lagged"``, ``"similar"`` (all support the hand's coupler
            constraints and implicit PD control; TAMSI does not).
    """

    time_step_s: float = DEFAULT_TIME_STEP_S
    contact_approximation: str = "lagged"

    def __post_init__(self) -> None:
        if not 1e-5 <= self.time_step_s <= 0.05:
            raise ValueError(f"time_step_s={self.time_step_s} is outside [1e-5, 0.05] s")
        if self.contact_approximation not in ("sap", "lagged", "similar"):
            raise ValueError(
                f"contact_approximation={self.contact_approximation!r} is not one of "
                "sap, lagged, similar"
            )

    def plant_config(self) -> MultibodyPlantConfig:
        """The Drake ``MultibodyPlantConfig`` for these settings."""
        return MultibodyPlantConfig(
            time_step=self.time_step_s,
            contact_model="hydroelastic_with_fallback",
            discrete_contact_approximation=self.contact_approximation,
        )
