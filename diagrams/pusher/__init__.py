"""The pusher-slider rig in Drake (Yu and Rodriguez, ICRA 2018) and its sensor and estimator
systems."""
