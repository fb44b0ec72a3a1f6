"""A pushed object's planar pose from vision and force sensing (Yu and Rodriguez, ICRA 2018):
the costs, noise identification, the vision-only and EKF baselines and the iSAM2 smoother."""
