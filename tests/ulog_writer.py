"""A minimal PX4 ULog writer for the tests: the file header, the format, subscription and data
messages of the topics given (ULog file format, version 1), nothing else."""

import struct

MAGIC = b"ULog\x01\x12\x35"
#: ULog field type -> struct code
TYPES = {"uint64_t": "Q", "int64_t": "q", "uint32_t": "I", "int32_t": "i", "uint16_t": "H", "int16_t": "h",
         "uint8_t": "B", "int8_t": "b", "float": "f", "double": "d", "bool": "?"}


def _message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def write_ulog(path, topics: dict) -> None:
    """Write ``topics`` (name -> ``(fields, data)``: ``fields`` a list of ``(type, count, name)``,
    count 0 for a scalar, the first ``("uint64_t", 0, "timestamp")``; ``data`` name -> an
    ``(N,)`` or ``(N, count)`` array) to the ULog ``path``, messages in time order."""
    out = bytearray(MAGIC + b"\x01" + struct.pack("<Q", 0))
    out += _message(b"B", bytes(40))                      # flag bits: no incompatible flags
    for name, (fields, _) in topics.items():
        text = name + ":" + "".join(f"{t}[{n}] {f};" if n else f"{t} {f};" for t, n, f in fields)
        out += _message(b"F", text.encode())
    for msg_id, name in enumerate(topics):
        out += _message(b"A", struct.pack("<BH", 0, msg_id) + name.encode())
    items = []
    for msg_id, (fields, data) in enumerate(topics.values()):
        fmt = "<" + "".join(TYPES[t] * (n or 1) for t, n, _ in fields)
        for i in range(len(data["timestamp"])):
            values = []
            for _, n, f in fields:
                values += list(data[f][i]) if n else [data[f][i]]
            items.append((int(data["timestamp"][i]), msg_id, struct.pack(fmt, *values)))
    items.sort(key=lambda x: (x[0], x[1]))
    for _, msg_id, payload in items:
        out += _message(b"D", struct.pack("<H", msg_id) + payload)
    with open(path, "wb") as f:
        f.write(bytes(out))
