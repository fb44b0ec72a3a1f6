"""Robot configuration estimation on the implicit contact manifold (thesis ch. 5):
constraint projection and the projection manifolds the MPF draws its dual particles from."""
