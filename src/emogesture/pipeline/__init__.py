"""Inference pipelines: audio to latents, latents to motion, generation and editing."""
