"""The object pose relative to the hand (thesis ch. 4): contact-manifold representations
(analytic, rejection-sampled, rollout) and the tracker used in the closed loop."""
