"""The face from the same speech: ARKit blendshapes, the SMPL-X jaw and eyes (:func:`track.face_track`)."""
