"""The output room: Rerun recordings, the viewer, atomic file writes, progress and Ctrl-C handling
(docs/design.md, "Rooms").
"""
