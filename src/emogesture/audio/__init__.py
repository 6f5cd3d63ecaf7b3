"""Audio front end (docs/design.md, 'Audio front end'): loading, Kaldi fbank, windows and normalisation,
augmentation, onsets.

    waveform, sr = load_audio("speech.wav")            # float32 mono 16 kHz, mean removed
    fbank = kaldi_fbank(waveform)                      # [frames, 128] log-mel, torch float32
    x = normalise_fbank(fbank)                         # (x - mean) / (2 std)
    windows = fbank_windows(x, [0, 500])               # [W, 1024, 128]
"""

from emogesture.audio.augment import augment_fbank, scramble_segments
from emogesture.audio.fbank import (
    FLOAT32_EPS,
    WINDOW_TYPES,
    FbankConfig,
    kaldi_fbank,
    kaldi_window,
    num_fbank_frames,
    rolled_fbank,
)
from emogesture.audio.io import TARGET_SAMPLE_RATE, audio_seconds, check_speech, load_audio, resample, without_mean
from emogesture.audio.mfcc import mfcc_from_log_mel
from emogesture.audio.noise import (NoiseSuppression, digital_silence, dynamic_range_db, fill_digital_silence,
                                   suppress_noise, suppression_strength)
from emogesture.audio.mel import (
    hz_to_mel_htk,
    hz_to_mel_slaney,
    kaldi_mel_banks,
    librosa_mel_banks,
    mel_to_hz_htk,
    mel_to_hz_slaney,
)
from emogesture.audio.onsets import detect_onsets, frame_energy, onset_strength, peak_pick, window_activity
from emogesture.audio.stft import power_spectrum, stft_power
from emogesture.audio.windows import (
    FBANK_FRAMES_PER_SECOND,
    FBANK_MEAN,
    FBANK_STD,
    WINDOW_CONTENT_FRAMES,
    WINDOW_FRAMES,
    WINDOW_SECONDS,
    denormalise_fbank,
    fbank_window,
    fbank_windows,
    RECORDING_NORMS,
    normalise_fbank,
    normalise_recording,
    seconds_to_fbank_frame,
    speech_level,
    window_starts,
)

__all__ = [
    "mfcc_from_log_mel",
    "NoiseSuppression",
    "dynamic_range_db",
    "suppress_noise",
    "digital_silence",
    "fill_digital_silence",
    "suppression_strength",
    "FBANK_FRAMES_PER_SECOND",
    "FBANK_MEAN",
    "FBANK_STD",
    "FLOAT32_EPS",
    "TARGET_SAMPLE_RATE",
    "WINDOW_CONTENT_FRAMES",
    "WINDOW_FRAMES",
    "WINDOW_SECONDS",
    "WINDOW_TYPES",
    "FbankConfig",
    "audio_seconds",
    "augment_fbank",
    "scramble_segments",
    "check_speech",
    "denormalise_fbank",
    "normalise_recording",
    "speech_level",
    "RECORDING_NORMS",
    "detect_onsets",
    "window_activity",
    "fbank_window",
    "fbank_windows",
    "frame_energy",
    "hz_to_mel_htk",
    "hz_to_mel_slaney",
    "kaldi_fbank",
    "kaldi_mel_banks",
    "kaldi_window",
    "librosa_mel_banks",
    "load_audio",
    "mel_to_hz_htk",
    "mel_to_hz_slaney",
    "normalise_fbank",
    "num_fbank_frames",
    "rolled_fbank",
    "onset_strength",
    "peak_pick",
    "power_spectrum",
    "resample",
    "seconds_to_fbank_frame",
    "stft_power",
    "window_starts",
    "without_mean",
]
