"""Classical planners and controllers: the paper's planning baselines and the drones' flight control.

Particle world (the "(H)" baselines of the paper's section "Baselines"):

* :mod:`.orca` — ORCA half-planes and RVO2's linear programs, vectorized over agents;
* :mod:`.rrt_star` — RRT* trees with rewiring and path shortcutting, one per agent;
* :mod:`.voronoi` — shortest routes along safe edges of a Voronoi diagram;
* :mod:`.controllers` — the one controller turning a desired velocity into MPE's discrete
  actions, and the path-tracking controller of the path planners;
* :mod:`.methods` — the policies ``h-orca``, ``h-rrtstar``, ``h-voronoi`` (Hungarian goal
  assignment every global step + a planner + the controller).

Drone world: :mod:`.drone_control` — motor mixing, a geometric (Lee) controller and the
drones' h-greedy reference.

Submodules are imported on demand, so importing this package loads nothing heavy.
"""
