"""The ``TactileSensor`` LeafSystem: per-patch binary contact and force from contact results.

A thin adapter: it maps the plant's contact results to (geometry -> patch, force) pairs and
calls the pure functions of :mod:`models.herb.tactile`. Readings are sampled periodically
(``period_s``) into discrete state, so they are piecewise constant like a real sensor's.
The noise of update k is drawn from ``np.random.default_rng([seed, k])``: a simulation is
reproducible from its seed, and re-evaluating an output never redraws it.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import Value
from pydrake.geometry import GeometryId
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from models.herb.tactile import SensorGroups, TactileLayout, TactileNoise, patch_force_magnitudes


def contact_pairs_by_patch(
    results: ContactResults, patch_index: dict[GeometryId, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Each contact pair that involves a patch, as (patch index, force on the patch, N, world).

    Returns:
        ``(pair_patch (K,), pair_force_W (K, 3))``; a pair between two patches (impossible
        on one hand, whose self-collisions are filtered) would count for the first.
    """
    patches, forces = [], []
    for i in range(results.num_hydroelastic_contacts()):
        info = results.hydroelastic_contact_info(i)
        surface = info.contact_surface()
        force_on_M = info.F_Ac_W().translational()
        for geometry, sign in ((surface.id_M(), 1.0), (surface.id_N(), -1.0)):
            if geometry in patch_index:
                patches.append(patch_index[geometry])
                forces.append(sign * force_on_M)
                break
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        pair = info.point_pair()
        force_on_B = info.contact_force()
        for geometry, sign in ((pair.id_B, 1.0), (pair.id_A, -1.0)):
            if geometry in patch_index:
                patches.append(patch_index[geometry])
                forces.append(sign * force_on_B)
                break
    return np.array(patches, dtype=int), np.array(forces, dtype=float).reshape(-1, 3)


class TactileSensor(LeafSystem):
    """Binary contact and force magnitude for each patch of a :class:`TactileLayout`.

    Input ports:
        contact_results: the plant's ``ContactResults`` (abstract).
    Output ports:
        contact: (P,) 1.0 where the (noisy) reading says contact, else 0.0.
        force: (P,) force magnitude per patch (N), with Gaussian noise.
        sensor_contact: (S,) readings of the pooled sensors, only when ``groups`` is given:
            the noise model applied to each group's summed true force (its draws come from
            ``default_rng([seed, k, 1])``, apart from the patches').

    Args:
        layout: patch layout; the output order is ``layout.patch_names``.
        patch_geometry: patch name -> its collision GeometryId on the hand.
        noise: the sensor's noise model (default: the thesis' 10% error during contact).
        seed: seed of the noise.
        period_s: sampling period (s).
        groups: patches pooled into a planar model's sensors (see :class:`SensorGroups`).
    """

    def __init__(
        self,
        layout: TactileLayout,
        patch_geometry: dict[str, GeometryId],
        *,
        noise: TactileNoise = TactileNoise(),
        seed: int = 0,
        period_s: float = 0.01,
        groups: SensorGroups | None = None,
    ):
        super().__init__()
        self.patch_names = layout.patch_names
        unknown = set(self.patch_names) - set(patch_geometry)
        if unknown:
            raise ValueError(f"no geometry for patches {sorted(unknown)}")
        self._patch_index = {patch_geometry[n]: i for i, n in enumerate(self.patch_names)}
        self._noise = noise
        self._seed = seed
        self.period_s = period_s
        count = len(self.patch_names)
        self._membership = None if groups is None else groups.membership(self.patch_names)
        sensors = 0 if groups is None else len(groups.names)
        self._contact_results = self.DeclareAbstractInputPort(
            "contact_results", Value(ContactResults()))
        self._state = self.DeclareDiscreteState(2 * count + sensors)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, 0.0, self._update)
        self.DeclareVectorOutputPort("contact", count, self._output_contact,
                                     prerequisites_of_calc={self.xd_ticket()})
        self.DeclareVectorOutputPort("force", count, self._output_force,
                                     prerequisites_of_calc={self.xd_ticket()})
        if groups is not None:
            self.DeclareVectorOutputPort("sensor_contact", sensors, self._output_sensors,
                                         prerequisites_of_calc={self.xd_ticket()})

    def _update(self, context, discrete_state) -> EventStatus:
        results = self._contact_results.Eval(context)
        pair_patch, pair_force = contact_pairs_by_patch(results, self._patch_index)
        forces = patch_force_magnitudes(pair_patch, pair_force, len(self.patch_names))
        step = int(round(context.get_time() / self.period_s))
        contact, noisy_force = self._noise.sample(
            forces, rng=np.random.default_rng([self._seed, step]))
        values = [contact.astype(float), noisy_force]
        if self._membership is not None:
            grouped, _ = self._noise.sample(self._membership @ forces,
                                            rng=np.random.default_rng([self._seed, step, 1]))
            values.append(grouped.astype(float))
        discrete_state.set_value(np.concatenate(values))
        return EventStatus.Succeeded()

    def _output_contact(self, context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state_vector().value()[: len(self.patch_names)])

    def _output_force(self, context, output: BasicVector) -> None:
        count = len(self.patch_names)
        output.SetFromVector(context.get_discrete_state_vector().value()[count:2 * count])

    def _output_sensors(self, context, output: BasicVector) -> None:
        values = context.get_discrete_state_vector().value()
        output.SetFromVector(values[2 * len(self.patch_names):])
