"""Algorithms shared by the methods: goal assignment (:mod:`.assignment`) and training.

Submodules are imported on demand (``from masp_lite.algos.assignment import hungarian``),
so importing this package costs nothing.
"""
