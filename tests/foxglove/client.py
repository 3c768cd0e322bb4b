"""An independent Foxglove WebSocket client, run as a separate process by the tests: no toaster and no foxglove-sdk import. It subscribes to every advertised
channel, decodes each message with the schema the server advertised (JSON channels validated
against their JSON Schema, protobuf channels decoded with the advertised FileDescriptorSet),
calls services, and prints what it saw as one JSON document.

foxglove-sdk 0.30 accepts only the subprotocol ``foxglove.sdk.v1`` (a client offering only
``foxglove.websocket.v1`` gets HTTP 400); its messages are those of ``foxglove.websocket.v1``.

    python client.py ws://127.0.0.1:PORT sally    # drive Sally-Anne over the node's services
    python client.py ws://127.0.0.1:PORT listen SECONDS
    python client.py ws://127.0.0.1:PORT follow SECONDS   # until the server closes (a run)
"""

from __future__ import annotations

import base64
import json
import struct
import sys
import time
import warnings
from typing import Any

import jsonschema
from google.protobuf import descriptor_pb2, descriptor_pool, json_format, message_factory
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

SUBPROTOCOL = "foxglove.sdk.v1"
warnings.filterwarnings("ignore", category=DeprecationWarning)  # connect() outside a `with`


def protobuf_class(schema_name: str, schema_b64: str) -> Any:
    """The message class of ``schema_name`` from a base64 FileDescriptorSet."""
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64)).file
    pool = descriptor_pool.DescriptorPool()
    added: set[str] = set()
    while len(added) < len(files):
        progress = False
        for fd in files:
            if fd.name not in added and all(d in added for d in fd.dependency):
                pool.Add(fd)
                added.add(fd.name)
                progress = True
        assert progress, "the FileDescriptorSet has a dependency it does not hold"
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


class Client:
    def __init__(self, url: str) -> None:
        self.ws = connect(url, subprotocols=[SUBPROTOCOL], max_size=None)
        assert self.ws.subprotocol == SUBPROTOCOL
        self.channels: dict[int, dict[str, Any]] = {}
        self.services: dict[str, dict[str, Any]] = {}
        self.subscriptions: dict[int, int] = {}
        self.decoders: dict[int, Any] = {}
        self.messages: dict[str, list[Any]] = {}
        self.responses: dict[int, Any] = {}
        self.server_info: dict[str, Any] = {}
        self.times: list[int] = []  # the server's time (its time capability), as it came
        self.closed = False
        self._next_sub = 1
        self._next_call = 1

    def pump(self, seconds: float) -> None:
        """Receive and handle everything for ``seconds``."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                frame = self.ws.recv(timeout=left)
            except TimeoutError:
                return
            except ConnectionClosed:
                self.closed = True
                return
            self.handle(frame)

    def handle(self, frame: str | bytes) -> None:
        if isinstance(frame, str):
            msg = json.loads(frame)
            op = msg["op"]
            if op == "serverInfo":
                self.server_info = msg
            elif op == "advertise":
                self.subscribe([c for c in msg["channels"] if c["id"] not in self.channels])
            elif op == "advertiseServices":
                for service in msg["services"]:
                    self.services[service["name"]] = service
            elif op == "serviceCallFailure":
                self.responses[msg["callId"]] = RuntimeError(msg["message"])
            return
        op = frame[0]
        if op == 1:  # message data
            sub, _stamp = struct.unpack_from("<IQ", frame, 1)
            channel = self.channels[self.subscriptions[sub]]
            self.messages.setdefault(channel["topic"], []).append(
                self.decoders[channel["id"]](frame[13:])
            )
        elif op == 2:  # time
            self.times.append(struct.unpack_from("<Q", frame, 1)[0])
        elif op == 3:  # service call response
            _service, call, n = struct.unpack_from("<III", frame, 1)
            encoding = frame[13 : 13 + n].decode()
            assert encoding == "json", encoding
            self.responses[call] = json.loads(frame[13 + n :])

    def subscribe(self, channels: list[dict[str, Any]]) -> None:
        subs = []
        for channel in channels:
            self.channels[channel["id"]] = channel
            self.decoders[channel["id"]] = self.decoder(channel)
            self.subscriptions[self._next_sub] = channel["id"]
            subs.append({"id": self._next_sub, "channelId": channel["id"]})
            self._next_sub += 1
        if subs:
            self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    @staticmethod
    def decoder(channel: dict[str, Any]) -> Any:
        if channel["encoding"] == "json":
            assert channel["schemaEncoding"] == "jsonschema", channel
            validator = jsonschema.Draft202012Validator(json.loads(channel["schema"]))

            def decode_json(data: bytes) -> Any:
                message = json.loads(data)
                validator.validate(message)
                return message

            return decode_json
        assert channel["encoding"] == "protobuf", channel
        cls = protobuf_class(channel["schemaName"], channel["schema"])
        return lambda data: json_format.MessageToDict(cls.FromString(data))

    def call(self, name: str, request: dict[str, Any], timeout: float = 30.0) -> Any:
        """Call a service with a JSON request; its JSON response (or raise its failure)."""
        deadline = time.monotonic() + timeout
        while name not in self.services:
            assert time.monotonic() < deadline, f"service {name} not advertised"
            self.pump(0.1)
        call_id, self._next_call = self._next_call, self._next_call + 1
        encoding = b"json"
        frame = struct.pack("<BIII", 2, self.services[name]["id"], call_id, len(encoding))
        self.ws.send(frame + encoding + json.dumps(request).encode())
        while call_id not in self.responses:
            assert time.monotonic() < deadline, f"no answer from {name}"
            self.pump(0.1)
        answer = self.responses.pop(call_id)
        if isinstance(answer, Exception):
            raise answer
        return answer

    def wait_for(self, check: Any, timeout: float = 60.0) -> Any:
        deadline = time.monotonic() + timeout
        while not (found := check()):
            assert time.monotonic() < deadline, "timed out"
            self.pump(0.1)
        return found

    def beliefs(self, holder: str) -> list[dict[str, Any]]:
        return [m for m in self.messages.get("/toaster/beliefs", []) if m["holder"] == holder]

    def summary(self) -> dict[str, Any]:
        return {
            "channels": sorted(
                (c["topic"], c["encoding"], c["schemaName"], c["schemaEncoding"], c["schema"])
                for c in self.channels.values()
            ),
            "services": sorted(self.services),
            "counts": {topic: len(found) for topic, found in sorted(self.messages.items())},
            "last": {topic: found[-1] for topic, found in sorted(self.messages.items())},
        }


ROOM = {"shape": "polygon", "points": [[0, 0], [5, 0], [5, 5], [0, 5]], "area_type": "room"}


def room(x: float) -> dict[str, Any]:
    return {**ROOM, "points": [[x + px, py] for px, py in ROOM["points"]]}


def held(client: Client, holder: str, target: str) -> dict[str, Any] | None:
    """SALLY's (or another's) newest belief that the marble is in ``target``."""
    found = client.beliefs(holder)
    for fact in found[-1]["facts"] if found else []:
        if (fact["subject"], fact["property"], fact["target"]) == ("MARBLE", "IsInRoom", target):
            return fact
    return None


def sally(client: Client) -> dict[str, Any]:
    """Sally-Anne with rooms, driven through the node's services: Sally leaves, the marble
    moves from ROOM to KITCHEN while Anne watches; Sally's belief is marked false."""
    for name, x in (("ROOM", 0), ("HALL", 10), ("KITCHEN", 20)):
        client.call("/toaster/add_area", {"name": name, "spec": room(x)})
    client.call("/toaster/set_pose", {"id": "SALLY", "x": 1, "y": 1, "kind": "human"})
    client.call("/toaster/set_pose", {"id": "ANNE", "x": 2, "y": 2, "kind": "human"})
    client.wait_for(lambda: client.beliefs("SALLY") and client.beliefs("ANNE"))
    client.call("/toaster/set_pose", {"id": "MARBLE", "x": 3, "y": 3})
    first = client.wait_for(lambda: held(client, "SALLY", "ROOM"))
    client.call("/toaster/set_pose", {"id": "SALLY", "x": 12, "y": 1, "kind": "human"})
    client.wait_for(lambda: _in(client, "SALLY", "HALL"))
    client.call("/toaster/set_pose", {"id": "MARBLE", "x": 22, "y": 3})
    false = client.wait_for(
        lambda: (f := held(client, "SALLY", "ROOM")) and f["false_belief"] and f
    )
    watch = client.call("/toaster/watch", {"agent": "SALLY", "property": "IsInRoom"})
    # subscribed before the tell (the server takes a client's messages in order)
    client.wait_for(lambda: any(c["topic"] == watch["topic"] for c in client.channels.values()))
    told = client.call(
        "/toaster/tell",
        {
            "speaker": "ANNE",
            "subject": "MARBLE",
            "property": "IsInRoom",
            "target": "KITCHEN",
            "listeners": ["SALLY"],
        },
    )
    corrected = client.wait_for(lambda: held(client, "SALLY", "KITCHEN"))
    client.wait_for(lambda: client.messages.get(watch["topic"]))
    try:
        client.call("/toaster/remove_area", {"name": "NOWHERE"})
        refused = ""
    except RuntimeError as exc:
        refused = str(exc)
    client.pump(1.5)
    return {
        "first": first,
        "false": false,
        "told": told,
        "corrected": corrected,
        "watched": client.messages[watch["topic"]],
        "refused": refused,
        **client.summary(),
    }


def _in(client: Client, agent: str, room_id: str) -> bool:
    found = client.messages.get("/toaster/facts", [])
    return any(
        (f["subject"], f["property"], f["target"]) == (agent, "IsInRoom", room_id)
        for m in found[-8:]
        for f in m["facts"]
    )


def main() -> None:
    url, what = sys.argv[1], sys.argv[2]
    client = Client(url)
    if what == "sally":
        result = sally(client)
    elif what == "follow":
        end = time.monotonic() + float(sys.argv[3])
        while not client.closed and time.monotonic() < end:
            client.pump(0.5)
        result = {
            **client.summary(),
            "closed": client.closed,
            "times": client.times,
            "beliefs": client.messages.get("/toaster/beliefs", []),
        }
    else:
        client.pump(float(sys.argv[3]))
        result = client.summary()
    result["server"] = client.server_info.get("name")
    result["capabilities"] = client.server_info.get("capabilities", [])
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
