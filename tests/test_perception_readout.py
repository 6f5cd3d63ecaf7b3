"""experiments/perception/perception_readout.py's read-outs: the nearest-mean posterior picks the nearest emotion mean,
and summing it with the head's log-probabilities lets either decide where the other is unsure."""


import numpy as np

from emogesture.data.beat import EMOTIONS
from emogesture.models.perception import EmotionPerception, LatentRange

from helpers import experiment_module


def _module():
    return experiment_module("perception/perception_readout")


def test_nearest_mean_posterior_and_the_sum_with_the_head():
    m = _module()
    rng = np.random.default_rng(0)
    labels = np.repeat(np.arange(8), 40)
    centres = rng.normal(size=(8, 16)) * 4
    latents = centres[labels] + rng.normal(size=(len(labels), 16))
    r = LatentRange.fit(latents, labels)
    probe = centres + 0.3 * rng.normal(size=(8, 16))
    post = r.log_posteriors(probe)
    assert np.allclose(np.exp(post).sum(1), 1.0) and (post.argmax(1) == np.arange(8)).all()
    assert (post.argmax(1) == r.distances(probe).argmin(1)).all()
    calibrated = EmotionPerception(list(EMOTIONS), r, r, {})
    fns = m.readouts(calibrated, r)
    flat = np.zeros((8, 8))  # a head that cannot tell: the latent decides
    assert (fns["head and nearest mean"](probe, flat).argmax(1) == np.arange(8)).all()
    sure = np.full((8, 8), -1e4)
    sure[:, 3] = 1e4  # a head that is certain of emotion 3 outvotes the latent
    assert (fns["head and nearest mean"](probe, sure).argmax(1) == 3).all()
    assert (fns["classifier head"](probe, sure).argmax(1) == 3).all()
