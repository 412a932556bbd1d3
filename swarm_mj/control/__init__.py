"""Controllers: U1..U4 for every drone from its state and reference."""

from .backstepping import TABLE4_GAINS, Backstepping, load_gains

__all__ = ["TABLE4_GAINS", "Backstepping", "load_gains"]
