"""Physical constants of the aerodynamic stages (docs/aero.md): air, rotors, plates."""

#: Air density (kg/m³), ISA sea level.
AIR_DENSITY = 1.225
#: Rotor radius (m): the drawn rotor discs of assets/quadrotor.xml (0.09 m, as the issue states).
ROTOR_RADIUS = 0.09
#: Height of the rotor plane above the centre of mass (m), the rotor discs of the asset.
ROTOR_PLANE_Z = 0.02
#: Drag coefficient of a rotor disc in the jet: a flat disc normal to the flow (Hoerner, Fluid-Dynamic
#: Drag, 1965, ch. 3: C_D = 1.17).
DISC_DRAG_COEFFICIENT = 1.17
#: Area (m²) of the hub the jet meets at the centre of a lower drone: the 0.12 m × 0.12 m hub box of
#: assets/quadrotor.xml (the paper's drone; a vehicle's own is ``QuadParams.body_area``).
BODY_AREA = 0.12 * 0.12
