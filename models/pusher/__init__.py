"""The pusher-slider rig of Yu and Rodriguez (ICRA 2018): carriage, force-sensing rods,
camera occlusion, pushing procedures and the sensor-log format."""
