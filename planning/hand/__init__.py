"""The hand-relative planning problem (thesis ch. 6): discretisation, the POMDP model,
its solution, the pre-contact A* search, the combined policy and the planners."""
