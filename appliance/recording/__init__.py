"""The drive recording format.

meta.toml, video or frames/, frames.csv, can.log, ptu.csv, truth.json (docs/interfaces.md).
"""

from appliance.recording.meta import CanDecoding, RecordingMeta, apply_meta, meta_from_config
from appliance.recording.reader import PtuTrack, Recording
from appliance.recording.writer import RecordingWriter

__all__ = [
    "CanDecoding",
    "PtuTrack",
    "Recording",
    "RecordingMeta",
    "RecordingWriter",
    "apply_meta",
    "meta_from_config",
]
