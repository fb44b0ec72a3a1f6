"""Generic POMDP machinery that imports no model of this project: tabular POMDPs, the
Cassandra format, benchmarks, QMDP, the discrete Bayes filter and the point-based solver."""
