"""The physics room: the MJCF world, the simulator and its force stages, the mixer, the vehicle's parameters, the
state, the wind, the observation, MuJoCo's step bridge and the aerodynamics (docs/design.md, "Rooms").
"""
