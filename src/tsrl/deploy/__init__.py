"""Deployment: export a run (tsrl.deploy.export, needs torch) and run it on a robot (no torch)."""
