"""Robustness: every command given bad input, and runs that fail for a physical or numerical reason.

Each bad-input case holds the command line's promise (docs/cli.md): exit status 2,
one line on stderr (``toywalk CMD: error: ...``) naming the problem, no output written (no partial
file, companion or temporary file), and a result already stored at the output path left as it was.
The commands run in the test process through the console script's entry point, with stderr read at
the file descriptor, so messages from C libraries (FFmpeg, HDF5) count as lines too.

- ``test_inputs.py``: for each input kind and each command that reads it:
  - parameter files (``gait``, ``simulate``, ``render``, ``fit``, ``diagnose``, ``track``): empty,
    binary, cut short, a trajectory or camera file in their place, unknown keys, NaN, a number as
    a string, a short vector, a folder, a missing file; physically impossible walkers for
    ``gait`` (negative mass, foot radius past the leg length, lateral radius past the fore-aft
    one, slope of 90 degrees, no gravity, inertia no body has); an uphill walker with no gait;
  - trajectories (``render``, ``fit``, ``diagnose``; ``sample`` in test_sampling.py): empty, cut
    inside a row, a missing or repeated column, a parameter file or binary bytes in their place,
    NaN and infinite values, times that go back, text for a number, a stance other than L/R, a
    negative standard deviation; an events file empty, cut, without its foot column, with a bad
    foot or an infinite time; metadata that is not JSON or not an object; a folder, a missing
    file, a camera file given as the trajectory; a walk with too few heel strikes to fit;
  - camera files and marker layouts (``render``, ``track``): empty, binary, cut short, a wrong
    matrix shape, NaN, an infinite or fractional image size, too few distortion coefficients, a
    bad ramp pose, duplicate or out-of-dictionary marker ids, an unknown dictionary or body, a
    side given as a string, no markers, each file in the other's place, JSON nested too deep;
  - videos (``track``): random bytes, zero bytes, cut in half, cut at its start, a CSV or an
    image named .mp4, a folder, a missing file, a camera of another image size;
  - calibration images (``calibrate``): random bytes, zero bytes, text, a folder, a missing file,
    an image without the board;
  - output paths of the wrong kind or in a missing folder (``simulate``, ``fit``, ``render``,
    ``diagnose``, ``demo``); misspelt names given to ``diagnose`` refused before any fit; the
    console script itself, in a separate process, printing one line.
- ``test_sampling.py`` (``sample``): fit files (empty, cut, binary, a list, a camera file, a failed
  fit, a covariance missing, of the wrong shape or with NaN, a NaN estimate, an impossible
  walker, an unknown free parameter, JSON nested too deep, an integer too long to read, a folder,
  missing); every bad trajectory above; chain files (zero bytes, random bytes, a CSV, a chain cut
  in half, an HDF5 file of other data, an ensemble without its datasets, a folder, a chain of
  another shape), each left as it was; ``--report`` naming a file; a run interrupted by Ctrl-C
  (the step under way finished, one line, status 130, the stored steps readable, then resumed to
  the requested length with every stored step unchanged); the console script killed with SIGTERM
  after a few steps, then resumed (marked slow: a separate process); a run interrupted before its
  first step (no file left); a chain whose walkers never moved summarised without a crash.
- ``test_failures.py``: a walker that falls (``simulate``: status 1, a status line saying where,
  the walk until the fall written whole and marked ``fell``); a fit whose solver stops before it
  converges (``fit``: status 1, IPOPT's status, one line on stderr, the fit file written whole
  with its status).
- ``test_fuzz.py``: the trajectory, parameter, camera and marker layout readers, fuzzed with
  Hypothesis (arbitrary bytes, and valid files with fields replaced, removed and added): each
  returns an object meeting its invariants or raises its own ValueError subclass with a one-line
  message, never another exception or a warning.
- ``test_no_unsafe_loading.py``: no module unpickles or evaluates anything (pickle, shelve,
  marshal, dill, joblib, ``allow_pickle``, ``yaml.load``, ``torch.load``, ``eval``, ``exec``): a
  static check of the source tree, shown to find each pattern in a planted example.
"""
