//! The discrete thin plate (DESIGN §4) and its multigrid solver.
