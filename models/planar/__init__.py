"""The hand-relative 2-D world (thesis model 1, sec. 3.5): object poses ``(x, y, theta)`` in
the planar hand frame ``H`` (origin on the palm surface, x forward along the push, y towards
finger F3, theta counter-clockwise seen from above).

- :mod:`models.planar.polygon`: batched convex-polygon queries (signed distance, penetration);
- :mod:`models.planar.hand`: the BarrettHand projected from the Drake model, sensors on it;
- :mod:`models.planar.cspace`: C-obstacles and contact-manifold iso-contours (Minkowski sums);
- :mod:`models.planar.pushing`: the quasi-static pushing transition model;
- :mod:`models.planar.observation`: the binary contact observation model;
- :mod:`models.planar.world`: the bundle of the above that estimators and planners use.
"""
