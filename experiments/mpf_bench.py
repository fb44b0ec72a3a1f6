"""``cmanip bench mpf``: per-update wall time of the CPF and MPF and the pushing model's
throughput, as medians over repeated updates measured in one run.

Setting (thesis sec. 4.3): the box, the medium sensor layout, 5 mm of hand travel per
update, particles in contact with the hand (the expensive case: every particle needs the
physics), a contact observation so that the MPF draws its dual particles. The thesis
reports 162 ms per update, 80 % of it in the physics model.
"""

from __future__ import annotations

import numpy as np

from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import ConventionalParticleFilter, ManifoldParticleFilter
from experiments.timing import median_ms
from models.planar.world import PlanarWorld

ACTION = np.array([0.005, 0.0, 0.0])


def _contact_belief(world: PlanarWorld, n: int, rng: np.random.Generator) -> np.ndarray:
    """n states of the box resting against the front of the hand."""
    states = world.sample_gaussian([0.16, 0.0, 0.0], [0.01, 0.02, 0.3], n, rng=rng)
    return world.sample_step(states, np.array([0.05, 0.0, 0.0]), rng=rng)


def run_mpf_bench(repeats: int = 30, seed: int = 0) -> dict:
    """Measure and print; return the report (``--json`` keys of the issue)."""
    rng = np.random.default_rng(seed)
    world = PlanarWorld.load("box", "medium")
    manifold = AnalyticManifold(world)
    cpf = ConventionalParticleFilter(world)
    mpf = ManifoldParticleFilter(world, manifold, dual_particles=25, mixing_rate=0.1)
    report = {}
    for n, suffix in ((100, ""), (10_000, "_10k")):
        states = _contact_belief(world, n, rng)
        belief = ParticleBelief.uniform(states)
        observation = world.sensing.true_contacts(states[:1])[0]
        if not observation.any():
            observation[0] = True
        reps = repeats if n <= 1000 else max(3, repeats // 6)
        for name, flt in (("cpf", cpf), ("mpf", mpf)):
            report[f"{name}_update_ms{suffix}"] = median_ms(
                lambda flt=flt, b=belief, o=observation: flt.update(b, ACTION, o, rng=rng), reps,
                f"{name} n={n}")
    # Baseline in the same run: the numpy reference backend (same algorithm, no kernels).
    reference = PlanarWorld.load("box", "medium", backend="numpy")
    states = _contact_belief(world, 100, rng)
    observation = world.sensing.true_contacts(states[:1])[0]
    report["cpf_update_ms_numpy_backend"] = median_ms(
        lambda: ConventionalParticleFilter(reference).update(
            ParticleBelief.uniform(states), ACTION, observation, rng=rng),
        max(3, repeats // 3), "cpf numpy")
    states = _contact_belief(world, 2000, rng)
    u = rng.random((len(states), world.uniforms_per_step(ACTION)))
    step_ms = median_ms(lambda: world.step(states, ACTION, u), max(3, repeats // 3),
                         "transition")
    report["transition_particle_mm_per_s"] = len(states) * ACTION[0] * 1000 / (step_ms / 1e3)
    report["settings"] = {"object": "box", "sensors": "medium", "travel_per_update_m": 0.005,
                          "mpf_dual_particles": 25, "mpf_mixing_rate": 0.1,
                          "repeats": repeats, "seed": seed}
    print(f"CPF n=100:    {report['cpf_update_ms']:8.2f} ms per update (median)", flush=True)
    print(f"MPF 100+25:   {report['mpf_update_ms']:8.2f} ms  "
          f"(ratio to CPF {report['mpf_update_ms'] / report['cpf_update_ms']:.2f})")
    print(f"CPF n=10000:  {report['cpf_update_ms_10k']:8.2f} ms")
    print(f"MPF 10000+25: {report['mpf_update_ms_10k']:8.2f} ms  "
          f"(ratio {report['mpf_update_ms_10k'] / report['cpf_update_ms_10k']:.2f})")
    print(f"CPF n=100 on the numpy reference backend: "
          f"{report['cpf_update_ms_numpy_backend']:8.2f} ms (compiled is "
          f"{report['cpf_update_ms_numpy_backend'] / report['cpf_update_ms']:.0f}x faster)")
    print(f"pushing model: {report['transition_particle_mm_per_s']:,.0f} particle-mm/s "
          "(2000 particles in contact, one thread)")
    return report
