"""Playback: 2-D matplotlib animations (:mod:`.anim2d`), 3-D meshcat scenes, the ``play`` command;
training curves of a run or of the shipped weights (:mod:`.progress`).
:mod:`masp_lite.viz.playground`: two methods side by side on one layout, SR / Steps / CR ticking (ipywidgets).

Submodules are imported on demand so that importing the package loads no plotting library.
"""
