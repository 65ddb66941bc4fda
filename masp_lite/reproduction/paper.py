"""The paper's numbers, typed in once: every table ``reproduce`` prints beside ours.

Read from the paper's tables "MPE" (``tab: mpe``), "MPE, varying team size"
(``tab: mpe_varying``), "OmniDrones" (``tab: omnidrones``), "OmniDrones, varying team size"
(``tab:omnidrones_varying``), "per-step time" (``tab: time_table``) and the ablations at N = 20
(``tab: ab``, ``tab: groupsize``, ``tab: globalsteps``; their MASP, 24.41 Steps, is another
run than the 25.61 of "MPE"). :mod:`.reproduce`,
:mod:`.claims` and the benchmarks read them from here.
"""
from __future__ import annotations

__all__ = ["PAPER"]


def _p(*cells):
    """Paper cells ``(steps, std, sr, std, cr, std)`` -> ``{"steps": (m, s) or None, ...}``."""
    s, ss, r, rs, c, cs = cells
    return {"steps": (s, ss), "sr": (r, rs), "cr": (c, cs)}


#: The paper's numbers: table -> (scenario, method) -> metric -> (mean, std); Steps None = "\".
PAPER = {
    "mpe": {
        ("mpe-5", "h-orca"): _p(16.38, 0.53, 0.72, 0.01, 0.57, 0.03),
        ("mpe-5", "h-rrtstar"): _p(7.58, 1.49, 0.99, 0.01, 3.41, 0.14),
        ("mpe-5", "h-voronoi"): _p(8.86, 1.27, 0.98, 0.01, 3.44, 0.25),
        ("mpe-5", "h-mappo"): _p(8.04, 1.53, 1.00, 0.00, 0.42, 0.02),
        ("mpe-5", "mappo"): _p(8.69, 1.24, 1.00, 0.00, 1.32, 0.38),
        ("mpe-5", "darl1n"): _p(None, None, 0.74, 0.02, 2.80, 0.53),
        ("mpe-5", "htamp"): _p(None, None, 0.65, 0.05, 1.63, 0.43),
        ("mpe-5", "mage-x"): _p(14.75, 0.60, 1.00, 0.00, 0.45, 0.02),
        ("mpe-5", "masp"): _p(7.54, 1.37, 1.00, 0.00, 0.47, 0.01),
        ("mpe-20", "h-orca"): _p(34.28, 3.22, 0.95, 0.03, 0.49, 0.04),
        ("mpe-20", "h-rrtstar"): _p(26.86, 2.27, 0.99, 0.01, 1.69, 0.05),
        ("mpe-20", "h-voronoi"): _p(28.72, 2.68, 1.00, 0.00, 1.80, 0.03),
        ("mpe-20", "h-mappo"): _p(27.43, 2.49, 1.00, 0.00, 0.75, 0.05),
        ("mpe-20", "mappo"): _p(None, None, 0.71, 0.02, 2.53, 1.02),
        ("mpe-20", "darl1n"): _p(None, None, 0.62, 0.03, 3.22, 1.23),
        ("mpe-20", "htamp"): _p(None, None, 0.05, 0.01, 1.54, 0.05),
        ("mpe-20", "mage-x"): _p(None, None, 0.75, 0.02, 1.78, 0.14),
        ("mpe-20", "masp"): _p(25.61, 2.10, 1.00, 0.00, 0.44, 0.03),
        ("mpe-50", "h-orca"): _p(60.66, 4.76, 0.97, 0.01, 0.30, 0.02),
        ("mpe-50", "h-rrtstar"): _p(58.68, 3.89, 0.99, 0.01, 1.39, 0.14),
        ("mpe-50", "h-voronoi"): _p(57.88, 5.43, 0.99, 0.01, 1.31, 0.42),
        ("mpe-50", "h-mappo"): _p(51.88, 4.06, 0.99, 0.01, 0.42, 0.75),
        ("mpe-50", "mappo"): _p(None, None, 0.01, 0.01, 0.78, 0.26),
        ("mpe-50", "darl1n"): _p(None, None, 0.49, 0.02, 1.14, 0.34),
        ("mpe-50", "htamp"): _p(None, None, 0.02, 0.01, 1.35, 0.21),
        ("mpe-50", "mage-x"): _p(None, None, 0.23, 0.01, 1.69, 0.37),
        ("mpe-50", "masp"): _p(47.46, 5.93, 0.99, 0.01, 0.23, 0.01),
    },
    "mpe-varying": {
        ("mpe-20to10", "h-orca"): _p(43.64, 3.86, 0.89, 0.01, 0.18, 0.02),
        ("mpe-20to10", "h-rrtstar"): _p(40.68, 3.37, 0.92, 0.01, 0.72, 0.14),
        ("mpe-20to10", "h-voronoi"): _p(40.18, 3.41, 0.93, 0.01, 0.86, 0.13),
        ("mpe-20to10", "masp"): _p(22.38, 3.04, 1.00, 0.00, 0.16, 0.03),
        ("mpe-50to20", "h-orca"): _p(None, None, 0.86, 0.01, 0.15, 0.03),
        ("mpe-50to20", "h-rrtstar"): _p(89.18, 4.88, 0.91, 0.01, 0.56, 0.05),
        ("mpe-50to20", "h-voronoi"): _p(88.73, 4.27, 0.91, 0.02, 0.67, 0.03),
        ("mpe-50to20", "masp"): _p(46.49, 4.49, 1.00, 0.00, 0.15, 0.01),
    },
    "omnidrones": {
        ("drone-5", "h-orca"): _p(260.10, 10.02, 0.98, 0.03, 0.00, 0.01),
        ("drone-5", "h-rrtstar"): _p(236.10, 9.47, 0.97, 0.01, 0.01, 0.01),
        ("drone-5", "h-voronoi"): _p(173.89, 12.91, 0.99, 0.02, 0.02, 0.01),
        ("drone-5", "h-mappo"): _p(185.34, 7.14, 1.00, 0.00, 0.01, 0.01),
        ("drone-5", "mappo"): _p(None, None, 0.50, 0.09, 0.01, 0.01),
        ("drone-5", "darl1n"): _p(None, None, 0.68, 0.02, 0.01, 0.01),
        ("drone-5", "htamp"): _p(None, None, 0.32, 0.08, 0.01, 0.01),
        ("drone-5", "mage-x"): _p(231.26, 19.32, 0.99, 0.01, 0.01, 0.01),
        ("drone-5", "masp"): _p(138.35, 13.57, 1.00, 0.00, 0.00, 0.00),
        ("drone-20", "h-orca"): _p(449.10, 14.86, 0.97, 0.03, 0.01, 0.03),
        ("drone-20", "h-rrtstar"): _p(438.23, 11.02, 0.97, 0.01, 0.03, 0.03),
        ("drone-20", "h-voronoi"): _p(437.43, 14.24, 0.93, 0.01, 0.01, 0.03),
        ("drone-20", "h-mappo"): _p(335.74, 13.07, 0.96, 0.01, 0.01, 0.01),
        ("drone-20", "mappo"): _p(None, None, 0.15, 0.03, 0.03, 0.02),
        ("drone-20", "darl1n"): _p(None, None, 0.15, 0.01, 0.05, 0.01),
        ("drone-20", "htamp"): _p(None, None, 0.14, 0.03, 0.04, 0.02),
        ("drone-20", "mage-x"): _p(None, None, 0.14, 0.03, 0.08, 0.02),
        ("drone-20", "masp"): _p(315.31, 14.52, 0.97, 0.01, 0.01, 0.01),
    },
    "omnidrones-varying": {
        ("drone-20to10", "h-orca"): _p(None, None, 0.68, 0.04, 0.00, 0.01),
        ("drone-20to10", "h-rrtstar"): _p(None, None, 0.61, 0.04, 0.01, 0.01),
        ("drone-20to10", "h-voronoi"): _p(490.35, 15.63, 0.85, 0.03, 0.01, 0.01),
        ("drone-20to10", "masp"): _p(426.73, 18.50, 0.94, 0.01, 0.01, 0.01),
    },
    # the ablations, N = 20; groupsize and globalsteps are keyed by the setting's value
    "ab": {
        ("mpe-20", "masp-rg"): _p(35.91, 2.73, 1.00, 0.00, 0.25, 0.02),
        ("mpe-20", "gm-mlp"): _p(None, None, 0.04, 0.01, 3.32, 0.02),
        ("mpe-20", "cae-mlp"): _p(28.25, 3.21, 1.00, 0.00, 0.17, 0.01),
        ("mpe-20", "masp"): _p(24.41, 2.66, 1.00, 0.00, 0.14, 0.01),
    },
    "groupsize": {
        ("mpe-20", 2): _p(28.85, 2.12, 1.00, 0.00, 0.15, 0.01),
        ("mpe-20", 3): _p(24.41, 2.66, 1.00, 0.00, 0.14, 0.01),
        ("mpe-20", 5): _p(23.78, 2.35, 1.00, 0.00, 0.14, 0.01),
    },
    "globalsteps": {
        ("mpe-20", 1): _p(24.23, 2.11, 1.00, 0.00, 0.12, 0.01),
        ("mpe-20", 3): _p(24.41, 2.66, 1.00, 0.00, 0.14, 0.01),
        ("mpe-20", 10): _p(29.59, 2.43, 1.00, 0.00, 0.16, 0.01),
    },
    # per-step time at N = 50, milliseconds (mean, std); the paper names the planners without "(H)"
    "per-step-time": {"h-orca": (39, 6), "h-rrtstar": (456, 10), "h-voronoi": (44, 5), "mappo": (13, 4),
                      "darl1n": (16, 3), "htamp": (14, 3), "mage-x": (20, 5), "masp": (14, 2)},
}
