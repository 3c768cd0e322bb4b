"""The Foxglove side of ``bench_live.py --foxglove``: a WebSocket client (the websockets
package, no toaster code) subscribed to every channel of ``toaster serve --foxglove``,
noting, on ``/toaster/facts``, when each human's IsInArea zone_<human> appears or ends in
area_manager's fact list.

    python benchmarks/foxglove_listener.py PORT SECONDS

Listens for SECONDS or until SIGINT, then prints one JSON object: ``seen`` [[human, inside,
receive wall ns]], as live_client.py's.
"""

from __future__ import annotations

import json
import signal
import struct
import sys
import time
import warnings

from websockets.sync.client import connect

warnings.filterwarnings("ignore", category=DeprecationWarning)


def main() -> None:
    port, seconds = int(sys.argv[1]), float(sys.argv[2])
    ws = connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], max_size=None)
    seen: list[list] = []
    inside_now: set[str] = set()
    subscription = None
    end = time.monotonic() + seconds
    # SIGINT only sets a flag: raised inside websockets' recv it could be swallowed there (a
    # listener that never stopped: bench_live's communicate timed out)
    stopped: list[int] = []
    signal.signal(signal.SIGINT, lambda *_: stopped.append(1))
    while not stopped and (left := end - time.monotonic()) > 0:
        try:
            frame = ws.recv(timeout=min(left, 0.2))
        except TimeoutError:
            continue
        now = time.time_ns()
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg["op"] == "advertise":  # every channel, as the app with toaster's layout
                subs = [{"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]
                for channel in msg["channels"]:
                    if channel["topic"] == "/toaster/facts":
                        subscription = channel["id"]
                ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            continue
        if frame[0] != 1 or struct.unpack_from("<I", frame, 1)[0] != subscription:
            continue
        facts = json.loads(frame[13:])
        if facts["producer"] != "area_manager":
            continue
        current = {
            f["subject"]
            for f in facts["facts"]
            if f["property"] == "IsInArea" and f["target"] == f"zone_{f['subject']}"
        }
        for human in current ^ inside_now:
            seen.append([human, human in current, now])
        inside_now = current
    print(json.dumps({"seen": seen}), flush=True)


if __name__ == "__main__":
    main()
