"""masp-lite: a laptop-scale course and reference implementation of MASP.

MASP (Multi-Agent Scalable Graph-based Planner) assigns goals with a graph-based Goal
Matcher and reaches them with a Coordinated Action Executor built on Group Information
Fusion, both trained with MAPPO. See ``notebooks/`` for the course.
"""
__version__ = "0.1.0"
