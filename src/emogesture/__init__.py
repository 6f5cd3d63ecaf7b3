"""emogesture: speech to emotional 3D body gestures (SMPL-X), after AMUSE (CVPR 2024).

Data flows one way:
audio -> fbank -> audio latents -> diffusion in motion-latent space -> motion features
-> SMPL-X sequence -> files.
"""

__version__ = "0.1.0"
