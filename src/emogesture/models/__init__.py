"""Neural networks: the speech disentanglement model (docs/design.md, 'Speech disentanglement model') and its
building blocks.

Models never read files; :mod:`emogesture.models.pretrained` turns a weights file into tensors.
"""
