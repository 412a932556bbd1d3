"""Exports of a flown scenario for real drones: ``swarm-mj export crazyflie`` (docs/export.md).

:mod:`.poly` fits degree-7 pieces joined up to the third derivative; :mod:`.checks` holds what a set must
pass; :mod:`.crazyflie` writes the Crazyflie's set (``uav_trajectories`` CSVs, the path, a manifest, the
cflib script :mod:`.upload`); :mod:`.flyback` flies a set back in the simulator (``swarm-mj run DIR``).
"""
