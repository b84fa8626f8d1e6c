"""Camera model and calibration, marker detection, pose estimation, angles, heel strikes, and the
synthetic video renderer (README.md, "Where things are").

FFmpeg (OpenCV's video back end) prints its own messages ("moov atom not found") on stderr, which
would add lines to the commands' one-line errors. OpenCV reads ``OPENCV_FFMPEG_LOGLEVEL`` once, when
a process first opens or writes a video, so it is set here, before any module of this package can
do so (-8: FFmpeg's AV_LOG_QUIET); a value the user has set is kept.
"""

import os as _os

_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
