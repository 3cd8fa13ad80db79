"""Experiments: grids of training runs defined in small TOML files, run on a process pool or Ray,
aggregated into a tidy CSV, learning curves with bootstrap confidence intervals and a summary; and
what studies read from saved runs: failure classes (failures) and milestone tables (milestones)."""
