"""Neural networks: the speech disentanglement model (SPEC §2) and its building blocks.

Models never read files; :mod:`emogesture.models.pretrained` turns a weights file into tensors.
"""
