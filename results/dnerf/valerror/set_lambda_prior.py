#!/usr/bin/env python3
"""Give a run λ_prior = VALUE, a setting no flag sets: in its config.json and in the evolution
settings its evo_state.safetensors records (the resume refuses the two disagreeing), each written
to a temporary file and renamed into place. run.sh calls it on a run started for one step.

    set_lambda_prior.py RUN VALUE
"""
import json
import os
import struct
import sys

run, value = sys.argv[1], float(sys.argv[2])


def replace(path, data):
    with open(path + ".tmp", "wb") as f:
        f.write(data)
    os.replace(path + ".tmp", path)


config = f"{run}/config.json"
c = json.load(open(config))
c["train"]["evogs"]["lambda_prior"] = value
replace(config, json.dumps(c, indent=2).encode())

state = f"{run}/evo_state.safetensors"
data = open(state, "rb").read()
n = struct.unpack("<Q", data[:8])[0]
header = json.loads(data[8 : 8 + n])
header["__metadata__"]["lambda_prior"] = repr(value)
text = json.dumps(header, separators=(",", ":")).encode()
text += b" " * ((8 - len(text) % 8) % 8)
replace(state, struct.pack("<Q", len(text)) + text + data[8 + n :])
