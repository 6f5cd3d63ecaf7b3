"""Deterministic English texts for the synthetic corpus: a small sentence grammar over word lists.

Each text is an endless stream of sentences drawn from a generator seeded by
``(seed, emotion, text index)``; a take uses as many sentences as its length needs, so every
speaker of a text speaks the same words (a longer take only appends the stream's next sentences).
The emotion colours a few word slots (feelings, interjections) the way BEAT's emotional scripts
do; sentence structure and most vocabulary are shared by all emotions.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import numpy as np

_PEOPLE = ("my brother", "our neighbour", "the old teacher", "my best friend", "the driver", "a young doctor",
           "the manager", "my grandmother", "the new student", "a stranger", "the baker", "our captain",
           "my sister", "the farmer", "a tall man", "the little girl", "everyone", "the whole team")
_PLACES = ("the market", "the station", "the river", "the old bridge", "the garden", "the library",
           "the harbour", "the village", "the mountain road", "the kitchen", "the school yard", "the museum",
           "the beach", "the city centre", "the forest", "the hospital", "the airport", "the back room")
_THINGS = ("a letter", "the keys", "a small box", "the tickets", "a heavy bag", "the photographs", "a map",
           "the money", "an umbrella", "the old radio", "a bottle of water", "the red bicycle", "a long list",
           "the paintings", "a basket of apples", "the broken clock", "a new phone", "the plans")
_VERBS_PAST = ("found", "carried", "lost", "opened", "painted", "brought", "forgot", "repaired", "sold",
               "hid", "showed me", "dropped", "counted", "packed", "cleaned", "returned")
_MOTION = ("walked to", "drove to", "ran towards", "came back from", "waited near", "moved into",
           "climbed up to", "hurried past", "looked around", "stayed at", "travelled to", "arrived at")
_TIMES = ("yesterday", "last summer", "on Monday morning", "after dinner", "this afternoon", "at midnight",
          "two weeks ago", "before sunrise", "every weekend", "in the evening", "last year", "right away")
_CONNECT = ("and then", "but", "so", "because", "while", "after that", "and suddenly", "although")
_FEEL = {
    "neutral": ("calm", "ready", "busy", "fine", "curious", "patient"),
    "happiness": ("happy", "delighted", "thrilled", "grateful", "proud", "cheerful"),
    "anger": ("furious", "angry", "annoyed", "outraged", "fed up", "bitter"),
    "sadness": ("sad", "lonely", "heartbroken", "tired", "hopeless", "miserable"),
    "contempt": ("unimpressed", "superior", "dismissive", "smug", "bored", "cold"),
    "surprise": ("amazed", "astonished", "shocked", "speechless", "stunned", "startled"),
    "fear": ("afraid", "terrified", "nervous", "scared", "anxious", "frightened"),
    "disgust": ("disgusted", "sick", "repelled", "revolted", "appalled", "nauseous"),
}
_EXCLAIM = {
    "neutral": ("Well,", "So,", "Now,", "Anyway,"),
    "happiness": ("Wonderful!", "Oh yes!", "How lovely!", "Great news!"),
    "anger": ("Enough!", "Unbelievable!", "How dare they!", "Stop it!"),
    "sadness": ("Oh no.", "Well.", "I suppose.", "If only."),
    "contempt": ("Please.", "Really?", "Of course.", "How typical."),
    "surprise": ("Wow!", "Really?", "No way!", "Oh my!"),
    "fear": ("Oh no!", "Listen!", "Wait!", "Careful!"),
    "disgust": ("Ugh!", "Yuck!", "Gross!", "Eww!"),
}
_TEMPLATES = (
    "{person} {verb} {thing} near {place} {time}.",
    "{time}, {person} {move} {place}, {conn} I felt {feel}.",
    "I was {feel} when {person} {verb} {thing}.",
    "{exclaim} {person} {move} {place} {time}.",
    "We {move} {place} {time}, {conn} {person} {verb} {thing}.",
    "Honestly, I feel {feel} about {thing} from {place}.",
    "{person} told me that {thing} was still at {place}.",
    "{exclaim} I cannot believe {person} {verb} {thing}.",
)


def sentence_stream(seed: int, emotion: str, text_index: int) -> Iterator[str]:
    """Endless deterministic sentences of one text, seeded by ``(seed, emotion, text_index)``."""
    if emotion not in _FEEL:
        raise ValueError(f"unknown emotion {emotion!r}")
    emo_id = list(_FEEL).index(emotion)
    rng = np.random.default_rng([seed, 7001, emo_id, text_index])

    def pick(options: tuple[str, ...]) -> str:
        return options[int(rng.integers(len(options)))]

    while True:
        template = pick(_TEMPLATES)
        sentence = template.format(
            person=pick(_PEOPLE), place=pick(_PLACES), thing=pick(_THINGS), verb=pick(_VERBS_PAST),
            move=pick(_MOTION), time=pick(_TIMES), conn=pick(_CONNECT), feel=pick(_FEEL[emotion]),
            exclaim=pick(_EXCLAIM[emotion]),
        )
        yield sentence[0].upper() + sentence[1:]


def make_text(seed: int, emotion: str, text_index: int, num_sentences: int) -> str:
    """The first ``num_sentences`` sentences of a text's stream, joined by spaces."""
    stream = sentence_stream(seed, emotion, text_index)
    return " ".join(next(stream) for _ in range(num_sentences))


def sentences_for_words(seed: int, emotion: str, text_index: int, min_words: int) -> int:
    """How many sentences of the stream it takes to reach ``min_words`` words (at least 1)."""
    count, words = 0, 0
    for sentence in sentence_stream(seed, emotion, text_index):
        count += 1
        words += len(words_of(sentence))
        if words >= min_words:
            return count
    raise AssertionError("unreachable")  # pragma: no cover


_WORD_RE = re.compile(r"[A-Za-z']+")


def words_of(text: str) -> list[str]:
    """The words of a text in order, punctuation stripped (``"Oh no!" -> ["Oh", "no"]``)."""
    return _WORD_RE.findall(text)


def syllables(word: str) -> int:
    """A rough English syllable count (vowel groups, silent final e), at least 1."""
    w = word.lower().strip("'")
    groups = re.findall(r"[aeiouy]+", w)
    n = len(groups)
    if w.endswith("e") and not w.endswith(("le", "ee", "ye")) and n > 1:
        n -= 1
    return max(1, n)
