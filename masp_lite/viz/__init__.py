"""Playback: 2-D matplotlib animations (:mod:`.anim2d`), 3-D meshcat scenes, the ``play`` command;
training curves of a run or of the shipped weights (:mod:`.progress`).

Submodules are imported on demand so that importing the package loads no plotting library.
"""
