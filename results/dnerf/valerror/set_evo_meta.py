#!/usr/bin/env python3
"""Set one entry of an `evo_state.safetensors`'s metadata (the evolution settings it records), in
place through a temporary file and a rename: run.sh's way to train with a λ_prior that no flag sets
(the run's config.json gets the same value, or the resume refuses the mismatch).

    set_evo_meta.py RUN/evo_state.safetensors KEY VALUE
"""
import json
import os
import struct
import sys

path, key, value = sys.argv[1:4]
data = open(path, "rb").read()
n = struct.unpack("<Q", data[:8])[0]
header = json.loads(data[8 : 8 + n])
header["__metadata__"][key] = value
text = json.dumps(header, separators=(",", ":")).encode()
text += b" " * ((8 - len(text) % 8) % 8)
with open(path + ".tmp", "wb") as f:
    f.write(struct.pack("<Q", len(text)) + text + data[8 + n :])
os.replace(path + ".tmp", path)
