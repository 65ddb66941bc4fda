"""Classical planners and controllers — pure algorithms, no policy logic.

Particle world (what the paper's "(H)" baselines plan with):

* :mod:`.orca` — ORCA half-planes and RVO2's linear programs, vectorized over agents;
* :mod:`.rrt_star` — RRT* trees with rewiring and path shortcutting, one per agent;
* :mod:`.voronoi` — shortest routes along safe edges of a Voronoi diagram;
* :mod:`.controllers` — the one controller turning a desired velocity into MPE's discrete
  actions, and the path-tracking controller of the path planners.

Drone world: :mod:`.geometric` — motor mixing and the geometric (Lee) controller.

The policies built on them (``h-orca``, ``h-rrtstar``, ``h-voronoi``, the drones'
``h-greedy``) are in :mod:`masp_lite.policies`. Submodules are imported on demand.
"""
