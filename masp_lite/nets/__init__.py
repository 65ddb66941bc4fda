"""MASP's networks (paper, section "Methodology") — torch only, no I/O.

* :mod:`.encoders` — ``SelfEncoder`` (eqs. 2-3) and ``CrossEncoder`` (eq. 4);
* :mod:`.fusion` — ``group_division`` and ``GroupInformationFusion`` (GCN over groups);
* :mod:`.decoding` — how the Goal Matcher's scores become goals;
* :mod:`.features` — what they see; :mod:`.masp` — ``GoalMatcher``, ``CoordinatedActionExecutor``,
  the centralized critics and ``MASPNets`` (all four, both worlds; :mod:`.drones` adds the drones' part).

Submodules are imported on demand, so importing this package costs nothing.
"""
