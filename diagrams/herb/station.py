"""The simulated HERB world as a Drake ``Diagram``: plant, tactile sensor, arm command, Meshcat.

The arm follows a joint trajectory through the plant's implicit PD controllers (desired
state port of the arm's model instance); the hand holds its preshape the same way. Later
issues replace the trajectory source by the controller system; everything else stays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
    SceneGraph,
)
from pydrake.multibody.meshcat import ContactVisualizer, ContactVisualizerParams
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    LogVectorOutput,
    TrajectorySource,
    VectorLogSink,
)
from pydrake.trajectories import PiecewisePolynomial

from diagrams.tactile_sensor import TactileSensor
from models.contact import SimulationConfig
from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout, TactileNoise
from models.herb.world import HerbWorld, populate_world


@dataclass
class HerbSimulation:
    """A built simulation diagram and handles to its parts."""

    diagram: Diagram
    plant: MultibodyPlant
    world: HerbWorld
    tactile: TactileSensor
    contact_log: VectorLogSink
    force_log: VectorLogSink
    visualizer: MeshcatVisualizer | None

    def initial_context(self, q_arm: np.ndarray) -> Context:
        """A context with the arm at ``q_arm`` (7,) rad, the hand in its preshape and the
        object resting at its scene pose."""
        context = self.diagram.CreateDefaultContext()
        plant_context = self.plant.GetMyMutableContextFromRoot(context)
        self.plant.SetPositions(plant_context, self.world.robot_positions(self.plant, q_arm))
        return context


def build_herb_simulation(
    scene: SceneSpec,
    arm_trajectory: PiecewisePolynomial,
    *,
    layout: TactileLayout,
    sim: SimulationConfig = SimulationConfig(),
    noise: TactileNoise = TactileNoise(),
    seed: int = 0,
    tactile_period_s: float = 0.01,
    meshcat: Meshcat | None = None,
) -> HerbSimulation:
    """Build the diagram of one scene whose arm follows ``arm_trajectory`` (7 joints, rad).

    Args:
        scene: the scene.
        arm_trajectory: joint positions over time; its derivative is the desired velocity.
        layout: tactile patch layout.
        sim: time step and contact approximation.
        noise: tactile noise model.
        seed: seed of the tactile noise.
        tactile_period_s: tactile sampling period (s).
        meshcat: when given, the scene is drawn there (illustration geometry plus contact
            forces) and recorded for replay.
    """
    builder = DiagramBuilder()
    plant, scene_graph, world = add_herb_plant(builder, scene, layout=layout, sim=sim)
    arm_command = builder.AddSystem(TrajectorySource(arm_trajectory, output_derivative_order=1))
    builder.Connect(arm_command.get_output_port(), plant.get_desired_state_input_port(world.wam))

    tactile = builder.AddSystem(TactileSensor(layout, world.hand.patch_geometry, noise=noise,
                                              seed=seed, period_s=tactile_period_s))
    tactile.set_name("tactile_sensor")
    builder.Connect(plant.get_contact_results_output_port(), tactile.get_input_port())
    contact_log = LogVectorOutput(tactile.GetOutputPort("contact"), builder, tactile_period_s)
    force_log = LogVectorOutput(tactile.GetOutputPort("force"), builder, tactile_period_s)

    visualizer = None if meshcat is None else add_meshcat(builder, plant, scene_graph, meshcat)
    diagram = builder.Build()
    return HerbSimulation(diagram, plant, world, tactile, contact_log, force_log, visualizer)


def add_herb_plant(builder: DiagramBuilder, scene: SceneSpec, *, layout: TactileLayout,
                   sim: SimulationConfig = SimulationConfig()
                   ) -> tuple[MultibodyPlant, SceneGraph, HerbWorld]:
    """Add the finalised plant of ``scene`` with the hand held in its preshape; the arm's
    desired-state input port (``plant.get_desired_state_input_port(world.wam)``) is left
    for the caller to drive."""
    plant, scene_graph = AddMultibodyPlant(sim.plant_config(), builder)
    world = populate_world(plant, scene_graph, scene, layout=layout)
    plant.Finalize()
    preshape = np.concatenate([world.hand.preshape, np.zeros_like(world.hand.preshape)])
    hand_command = builder.AddSystem(ConstantVectorSource(preshape))
    builder.Connect(hand_command.get_output_port(),
                    plant.get_desired_state_input_port(world.hand.instance))
    return plant, scene_graph, world


def add_meshcat(builder: DiagramBuilder, plant: MultibodyPlant, scene_graph: SceneGraph,
                meshcat: Meshcat) -> MeshcatVisualizer:
    """Draw the scene's illustration geometry and its contact forces in ``meshcat``."""
    visualizer = MeshcatVisualizer.AddToBuilder(
        builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration))
    ContactVisualizer.AddToBuilder(
        builder, plant, meshcat,
        ContactVisualizerParams(newtons_per_meter=40.0, newton_meters_per_meter=1.0))
    return visualizer
