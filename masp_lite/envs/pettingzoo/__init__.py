"""PettingZoo faces of the worlds (one episode each): :mod:`.particle` and :mod:`.drones`.

Build them with :func:`masp_lite.envs.parallel_env`; :mod:`.base` holds what both share.
"""
