"""Validation of the aerodynamic models against real flight logs (docs/validation.md).

``swarm-mj validate downwash`` decodes the Neural-Swarm raw Crazyflie logs (:mod:`.decode`,
:mod:`.flight`), computes each drone's measured residual force with the dataset's own system
identification (:mod:`.sysid`), finds the passes of one drone under another (:mod:`.passes`),
predicts the force with our jet model, gym-pybullet-drones' and none (:mod:`.predict`,
:mod:`.analysis`) and tabulates the errors (:mod:`.report`).
"""
