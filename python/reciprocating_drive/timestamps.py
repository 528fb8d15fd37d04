"""ISO 8601 timestamps in the time column of a CSV input (docs/twin.md "Timestamps"), as plant
historians export them: `2026-11-28T08:00:00.123Z`, `2026-11-28T09:00:00.123+01:00`, or local time
without an offset read in a named zone (`--timezone Europe/Berlin`, IANA's database through the
standard library's zoneinfo, so that the changes to and from daylight-saving time are those the
zone had on that date).

The run's time origin is the whole UTC second of the first sample (as for an OPC UA source,
plant/sources/opcua.py); the twin works, and writes, in seconds from it. Times are counted in whole
microseconds (the resolution of `datetime`), so t = (microseconds since the origin) / 1e6 is the
correctly rounded double of the exact value.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import datetime as dt
import re
import zoneinfo

EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
_US = dt.timedelta(microseconds=1)

#: What makes a time field a timestamp rather than a number: a calendar date first (YYYY-MM-DD,
#: then T or a space). A number never starts so, so the two are told apart by their first field.
LOOKS_ISO = re.compile(r"\s*\d{4}-\d{2}-\d{2}[T ]", re.ASCII)
#: The forms read: date, hours and minutes, optional seconds with any number of fraction digits
#: (a decimal comma was turned into a point with the ';' separator), optional Z or ±hh[:mm].
_ISO = re.compile(
    r"(\d{4}-\d{2}-\d{2})[T ](\d{2}:\d{2}(?::\d{2}(?:[.,]\d+)?)?)(Z|[+-]\d{2}(?::?\d{2})?)?",
    re.ASCII | re.IGNORECASE,
)


class TimestampError(ValueError):
    """A bad timestamp; the message has no line number (the caller adds it)."""


def zone(name: str | None) -> zoneinfo.ZoneInfo | None:
    """The named zone, ValueError (naming the option) when IANA's database has no such zone."""
    if name is None:
        return None
    try:
        return zoneinfo.ZoneInfo(name)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ValueError(
            f"--timezone {name!r}: not a time zone of the IANA database (for example "
            "Europe/Berlin, America/Chicago, UTC)"
        ) from None


def parse(raw: str) -> dt.datetime:
    """The timestamp as a datetime, naive when it has no offset (TimestampError if malformed)."""
    m = _ISO.fullmatch(raw.strip())
    if m is None:
        raise TimestampError(f"{raw.strip()!r} is not an ISO 8601 timestamp")
    date, clock, off = m.groups()
    # Python's reader takes at most 6 fraction digits: more are rounded to the microsecond here
    # (below the resolution the twin keeps, docs/twin.md "Input").
    us = 0
    if "." in clock or "," in clock:
        clock, frac = re.split(r"[.,]", clock)
        q, r = divmod(int(frac) * 10**6, 10 ** len(frac))
        us = q + (2 * r >= 10 ** len(frac))  # to the nearest microsecond
    text = f"{date}T{clock}" + ("" if off is None else ("+00:00" if off in "zZ" else off))
    try:
        d = dt.datetime.fromisoformat(text)
    except ValueError as e:
        raise TimestampError(f"{raw.strip()!r} is not a valid timestamp ({e})") from None
    return d + dt.timedelta(microseconds=us)


class Clock:
    """Timestamps of one input to microseconds since the Unix epoch (UTC), and from them seconds
    since the run's origin. Local times without an offset are read in `tz`; in the hour that a
    change back from daylight-saving time repeats, the reading not before the previous sample is
    taken (the data go forward in time), and a local time that the change forward skips is an
    error."""

    def __init__(self, tz: str | None = None, origin_us: int | None = None):
        self.tz_name = tz
        self.tz = zone(tz)
        self.origin_us = origin_us
        self.prev_us: int | None = None
        self.repeated_hour = False  # a timestamp fell in a repeated hour (reported once)

    def unix_us(self, raw: str) -> int:
        d = parse(raw)
        if d.tzinfo is None:
            if self.tz is None:
                raise TimestampError(
                    f"{raw.strip()!r} has no UTC offset (Z or ±hh:mm): for local times give the "
                    "zone, --timezone (for example Europe/Berlin)"
                )
            d = self._local(d, raw)
        return (d - EPOCH) // _US

    def _local(self, naive: dt.datetime, raw: str) -> dt.datetime:
        readings = []
        for fold in (0, 1):
            d = naive.replace(tzinfo=self.tz, fold=fold)
            # A time that does not exist (skipped when the clocks go forward) does not come back
            # unchanged from UTC.
            if d.astimezone(dt.UTC).astimezone(self.tz).replace(tzinfo=None) == naive:
                readings.append(d)
        if not readings:
            raise TimestampError(
                f"{raw.strip()!r} does not exist in {self.tz_name} (the clocks skip it when "
                "daylight-saving time begins)"
            )
        us = sorted({(d - EPOCH) // _US for d in readings})
        if len(us) > 1:
            self.repeated_hour = True
            later = [u for u in us if self.prev_us is None or u >= self.prev_us]
            pick = later[0] if later else us[-1]
        else:
            pick = us[0]
        return EPOCH + dt.timedelta(microseconds=pick)

    def seconds(self, raw: str) -> float:
        """Seconds since the origin (set to the first timestamp's whole UTC second)."""
        us = self.unix_us(raw)
        self.prev_us = us
        if self.origin_us is None:
            self.origin_us = us - us % 1_000_000
        return (us - self.origin_us) / 1e6

    @property
    def origin(self) -> float | None:
        """The origin in Unix seconds (a whole number)."""
        return None if self.origin_us is None else self.origin_us / 1e6

    def origin_text(self) -> str:
        d = EPOCH + dt.timedelta(microseconds=self.origin_us)
        return d.strftime("%Y-%m-%dT%H:%M:%SZ")
