"""HERB in Drake: the station (plant, scene, tactile sensors), the straight push and the
closed-loop diagram with its systems."""
