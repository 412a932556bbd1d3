"""The control period, written once: the typed state records (records), one compiled function per stage over them
(period) and the chunk driver built from those functions (fast); the per-period driver is Sim.step,
SwarmEnv.step and the policy (docs/design.md, "The control period, written once").
"""
