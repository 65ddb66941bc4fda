"""MASP's networks (paper, section "Methodology").

* :mod:`.encoders` — ``SelfEncoder`` (eqs. 2-3) and ``CrossEncoder`` (eq. 4);
* :mod:`.fusion` — ``group_division`` and ``GroupInformationFusion`` (GCN over groups);
* :mod:`.policies` — ``GoalMatcher``, ``CoordinatedActionExecutor``, the centralized
  critics, ``MASPNets`` (all four) and ``MASPPolicy`` (the ``masp`` method).

Submodules are imported on demand, so importing this package costs nothing.
"""
