"""Rocket flight logs as flight computers write them, in one time-aligned form.

[`read_rocket_log`][] reads the files of one flight (AltOS CSV from TeleMega and
TeleMetrum, CATS exports, altimeter CSVs of any layout through a column map),
cleans what flight computers leave behind (duplicate rows, dropouts, rate changes,
a late start, corrupt trailing rows), converts every channel to SI under
plausibility checks, puts every stream on one clock (seconds since liftoff) and
finds the flight's events (liftoff, burnout, apogee, deployments) from the data.

The result is a [`RocketLog`][]: named [`Channel`][]s, each with its own time base
(streams differ in rate: a 400 Hz accelerometer beside a 20 Hz barometer), the
[`Event`][]s with how each was found, the files read and one message per thing
cleaned or inferred.

**Channel names and units** (a channel is present only where a log has it):

| name | unit | meaning |
|---|---|---|
| `pressure` | Pa | static pressure at the barometer |
| `altitude` | m | barometric altitude above the pad (the log's own pre-liftoff samples are its zero where it has them) |
| `accel_axial` | m/s^2 | specific force along the body axis, nose positive, **gravity included**: what an ideal accelerometer reads, about +g on the pad, 0 in free fall, -drag/mass in the coast. Logs that remove 1 g (AltOS, CATS filtered) get g0 = 9.80665 m/s^2 added back, with a message. |
| `accel_x`, `accel_y`, `accel_z` | m/s^2 | 3-axis specific force in the sensor's axes, gravity included |
| `gyro_x`, `gyro_y`, `gyro_z` | rad/s | 3-axis rates in the sensor's axes |
| `velocity` | m/s | vertical speed as the log gives it (a flight computer's Kalman filter or a derivative of altitude: `filtered` says which) |
| `gnss_lat`, `gnss_lon` | deg | GNSS position (degrees, as receivers give them) |
| `gnss_alt` | m | GNSS altitude above mean sea level, as the receiver gives it |
| `temperature` | K | sensor temperature |

Any other name a column map gives is kept as it is mapped (SI by its unit).
"""

import dataclasses
import os
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ._format import LogError


G0 = 9.80665

CHANNEL_UNITS = {
    "pressure": "Pa",
    "altitude": "m",
    "accel_axial": "m/s^2",
    "accel_x": "m/s^2",
    "accel_y": "m/s^2",
    "accel_z": "m/s^2",
    "gyro_x": "rad/s",
    "gyro_y": "rad/s",
    "gyro_z": "rad/s",
    "velocity": "m/s",
    "gnss_lat": "deg",
    "gnss_lon": "deg",
    "gnss_alt": "m",
    "temperature": "K",
}
EVENT_NAMES = ("liftoff", "burnout", "apogee", "drogue", "main", "landing")


@dataclasses.dataclass(frozen=True)
class Channel:
    """One measured quantity on its own time base.

    **Fields:**

    - `t`: sample times, s since liftoff, strictly increasing, shape `(n,)`.
    - `values`: SI values, shape `(n,)` (units in the module's table).
    - `source`: where it came from, e.g. `"flight.csv: column 'alt(ft)' (ft)"`.
    - `filtered`: `True` when the flight computer smoothed or estimated it (a Kalman
      speed, a filtered altitude), `False` for a raw sensor reading.
    """

    t: np.ndarray
    values: np.ndarray
    source: str
    filtered: bool = False

    def __len__(self) -> int:
        return len(self.t)

    @property
    def rate(self) -> float:
        """Median sample rate, Hz."""
        return float(1.0 / np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0


@dataclasses.dataclass(frozen=True)
class Event:
    """A flight event found in the data.

    **Fields:**

    - `t`: time, s since liftoff (liftoff itself is at 0).
    - `how`: one sentence saying from which channel and by which rule it was found.
    - `value`: the quantity that marks it, where one does (apogee altitude in m,
      burnout speed in m/s, ...), else `nan`.
    """

    t: float
    how: str
    value: float = float("nan")


@dataclasses.dataclass(frozen=True)
class RocketLog:
    """One rocket flight's logs on one clock, in SI.

    **Fields:**

    - `channels`: name to [`Channel`][] (names and units in the module's table).
    - `events`: name to [`Event`][], for those of `liftoff`, `burnout`, `apogee`,
      `drogue`, `main`, `landing` the data show; `liftoff` is always present, at 0.
    - `files`: the files read, in the order read.
    - `messages`: one line per thing cleaned or inferred (duplicate rows dropped, a
      rate change, a late start, trailing rows dropped, a unit taken from the header,
      gravity added back, ...), each naming the file and column.
    - `time_offsets`: per file, the file's own time at liftoff, s (add it to a
      channel's `t` to get the time in the file).
    - `pad`: what the log says about the pad before liftoff, where it has samples
      there: `pressure` (Pa), `gnss_lat`, `gnss_lon` (deg), `gnss_alt` (m),
      `altitude_offset` (m subtracted from the file's altitude).
    """

    channels: dict[str, Channel]
    events: dict[str, Event]
    files: tuple[pathlib.Path, ...]
    messages: tuple[str, ...] = ()
    time_offsets: dict[str, float] = dataclasses.field(default_factory=dict)
    pad: dict[str, float] = dataclasses.field(default_factory=dict)

    def __getitem__(self, name: str) -> Channel:
        return self.channels[name]

    def __contains__(self, name: str) -> bool:
        return name in self.channels


def read_rocket_log(
    source: str | os.PathLike | Sequence[str | os.PathLike],
    column_map: Mapping[str, Any] | str | os.PathLike | None = None,
) -> RocketLog:
    """Read the logs of one rocket flight.

    **Arguments:**

    - `source`: a `rocket.toml` (its `[log.*]` tables' `file` entries name the logs,
      relative to it), or one log file, or a list of the log files of one flight.
    - `column_map`: which column holds which channel, in the syntax of every column
      map (`{"altitude": {"column": "alt(ft)", "unit": "ft"}}`), as a dict or a
      `.json` / `.toml` file. For several files or several streams in one file it is
      `{"streams": [{"file": "logs/a.csv", "time": "ts", "altitude": ...}, ...]}`.
      An accelerometer's entry may say `"gravity": "included"` or `"removed"`, any
      entry `"filtered": true`. Default: the map next to the `rocket.toml`
      (`columns.json`), else a shipped one for the flight, else the layout the
      files' headers show (AltOS, CATS, or column names with units in brackets).

    **Returns:**

    A [`RocketLog`][].

    **Raises:**

    [`LogError`][] with one line naming file, column, row and value for anything
    that cannot be used (a non-numeric cell mid-file, time running backwards, a
    unit that the data contradict, no column for a channel).
    """
    raise NotImplementedError("the readers land in the next commit")
