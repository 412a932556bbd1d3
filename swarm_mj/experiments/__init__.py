"""The experiments room: one run (runner), many seeded runs (sweep, stress), the process pool they share and the
summary table (docs/design.md, "Rooms").
"""
