"""Training: Lightning modules and the shared run machinery (checkpoints, logging, resume)."""
