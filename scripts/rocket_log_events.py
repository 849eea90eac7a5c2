"""The events and cleaning of each rocket flight in a data folder, as the markdown
table of the rocket-logs guide.

    python scripts/rocket_log_events.py DATA/rockets
"""

import pathlib
import sys
import time

from diffpegasus._log._rocketlogs import read_rocket_log


def main(folder: str) -> None:
    root = pathlib.Path(folder)
    print(
        "| flight | channels (rate) | liftoff in the file | burnout | apogee | "
        "drogue | main | landing | cleaned | read |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for toml in sorted(root.glob("*/rocket.toml")):
        start = time.perf_counter()
        log = read_rocket_log(toml)
        seconds = time.perf_counter() - start
        chans = ", ".join(
            f"{n} ({c.rate:.0f} Hz)" for n, c in log.channels.items() if "." not in n
        )
        offset = next(iter(log.time_offsets.values()))
        ev = log.events

        def at(name, ev=ev):
            e = ev.get(name)
            return "-" if e is None else f"{e.t:.2f} s"

        apogee = ev["apogee"]
        cleaned = sum(
            any(w in m for w in ("dropped", "dropouts", "rate changes", "starts"))
            for m in log.messages
        )
        print(
            f"| {toml.parent.name} | {chans} | {offset:+.3f} s | {at('burnout')} | "
            f"{apogee.t:.2f} s, {apogee.value:.1f} m | {at('drogue')} | {at('main')} | "
            f"{at('landing')} | {cleaned} | {seconds:.2f} s |"
        )


if __name__ == "__main__":
    main(sys.argv[1])
