"""Particle beliefs and the filters that update them: the conventional (CPF) and manifold
(MPF) particle filters, kernel density estimates and log-space helpers."""
