"""Quadruple sampling: (c1 s1, c2 s1, c1 s2, c2 s2), one emotion, aligned window positions."""

import numpy as np
import pytest

from emogesture.data.quadruples import QuadrupleIndex, WindowLabels
from emogesture.errors import EmogestureError


def labels(texts_emotions, speakers, windows_per_take=3):
    rows = [(t, s, e, 5.0 * k) for t, e in texts_emotions for s in speakers for k in range(windows_per_take)]
    t, s, e, st = map(np.array, zip(*rows))
    return WindowLabels(text=t, speaker_id=s, emotion=e, start_s=st)


def test_structure_of_drawn_quadruples():
    w = labels([(1, 0), (2, 0), (65, 1), (66, 1), (67, 1)], speakers=(1, 2, 3))
    index = QuadrupleIndex(w)
    rng = np.random.default_rng(0)
    seen_emotions = set()
    for _ in range(200):
        q = index.draw(rng)
        i = np.array(q.indices)
        assert len(set(w.emotion[i])) == 1 and w.emotion[i[0]] == q.emotion
        c1, c2, c1b, c2b = w.text[i]
        s1, s1b, s2, s2b = w.speaker_id[i]
        assert c1 == c1b and c2 == c2b and c1 != c2
        assert s1 == s1b and s2 == s2b and s1 != s2
        assert w.start_s[i[0]] == w.start_s[i[2]] and w.start_s[i[1]] == w.start_s[i[3]]
        assert q.speakers == (s1, s1, s2, s2)
        seen_emotions.add(q.emotion)
    assert seen_emotions == {0, 1}
    # the same seed gives the same draws
    a = [QuadrupleIndex(w).draw(np.random.default_rng(5)) for _ in range(2)]
    assert a[0] == a[1]


def test_held_out_first_text_and_errors():
    w = labels([(1, 0), (2, 0), (3, 0)], speakers=(1, 2))
    index = QuadrupleIndex(w, first_texts={3})
    rng = np.random.default_rng(1)
    assert all(w.text[index.draw(rng).indices[0]] == 3 for _ in range(50))
    with pytest.raises(EmogestureError, match="no quadruples"):
        QuadrupleIndex(labels([(1, 0), (65, 1)], speakers=(1, 2)))
    with pytest.raises(EmogestureError, match="no quadruples"):
        QuadrupleIndex(labels([(1, 0), (2, 0)], speakers=(1,)))
