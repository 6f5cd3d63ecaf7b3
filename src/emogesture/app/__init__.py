"""``emogesture app``: a web page to animate speech, built with Gradio (``pip install 'emogesture[app]'``).

Upload or record speech; choose the emotion (the speech's own, a label, a second recording or a timeline of
keyframes) and its weight, the speaker style from a recording, the seed and the number of samples; get the
video, a 3D view of the skinned mannequin playing in step with the speech (drag to turn it), the emotion
perceived in every 10-s window, and the npz, bvh, glb, fbx and mp4 files. Every request writes into its own
new folder, so two people using the page at once get their own results; a bad input is a message in the page
and the server goes on. It listens on 127.0.0.1 unless told otherwise, and is never shared through Gradio's
public links; on any other address visitors need its token (``?token=...`` on the page's URL, as
:mod:`emogesture.access` says). Recordings of more than ten minutes (``--max-upload-minutes``) or files of
more than 150 MB (``--max-upload-mb``) are refused with a message.
"""

from emogesture.app.page import build_app, serve

__all__ = ["build_app", "serve"]
