"""Live animation: speech streamed over a WebSocket, gestures streamed back (``emogesture live``)."""
