#!/usr/bin/env python3
"""Writes the committed seed corpus of fuzz_model_file (tests/fuzz/corpus/model_file/).

The files are built from docs/model-format.md alone, independently of runtime/nn/model_file.cpp,
so the unit test that loads tiny_valid.mcnn also checks that the reader follows the document.
Re-run after a format change:   python3 tests/fuzz/make_model_corpus.py
"""
import json
import os
import struct
import sys
import zlib

MAGIC = b"MOCAPNN\0"
VERSION = 1
HEADER_BYTES = 48
ALIGN = 16
OP_CONV2D, OP_ACTIVATION = 1, 8
ACT_NONE, ACT_SIGMOID = 0, 4
PAD_SAME = 0


def align(n):
    return (n + ALIGN - 1) // ALIGN * ALIGN


def layer(name, op, inputs, activation, out_channels=0, weights=-1, bias=-1):
    return {"name": name, "op": op, "inputs": inputs, "kernel_h": 1, "kernel_w": 1,
            "stride_h": 1, "stride_w": 1, "padding": PAD_SAME, "out_channels": out_channels,
            "activation": activation, "weights": weights, "bias": bias, "alpha": -1,
            "resize_factor": 1}


def tiny():
    """A 1x1 convolution 3 -> 2 channels with bias, then a sigmoid."""
    tensors = [("conv_w", [1, 1, 3, 2], [0.5, -1.0, 2.0, 0.25, 1.5, -0.75]),
               ("conv_b", [2], [0.125, -0.5])]
    meta = {"name": "tiny", "input_channels": 3, "tensors": [],
            "layers": [layer("conv", OP_CONV2D, [0], ACT_NONE, 2, 0, 1),
                       layer("sigmoid", OP_ACTIVATION, [1], ACT_SIGMOID)],
            "outputs": [{"name": "out", "value": 2}]}
    data = b""
    for name, shape, values in tensors:
        meta["tensors"].append({"name": name, "shape": shape, "offset": len(data),
                                "elements": len(values)})
        blob = struct.pack("<%df" % len(values), *values)
        data += blob + b"\0" * (align(len(blob)) - len(blob))
    return meta, data


def assemble(meta, data, version=VERSION, flags=0):
    text = json.dumps(meta, separators=(",", ":")).encode()
    data_offset = align(HEADER_BYTES + len(text))
    size = data_offset + len(data) + 4
    head = MAGIC + struct.pack("<IIQQQQ", version, flags, size, len(text), data_offset, len(data))
    body = head + text + b"\0" * (data_offset - HEADER_BYTES - len(text)) + data
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "corpus", "model_file")
    os.makedirs(out, exist_ok=True)
    meta, data = tiny()
    good = assemble(meta, data)
    seeds = {"tiny_valid.mcnn": good,
             "bad_checksum.mcnn": good[:-1] + bytes([good[-1] ^ 0x5A]),
             "truncated.mcnn": good[:len(good) // 2],
             "newer_version.mcnn": assemble(meta, data, version=VERSION + 1)}
    bad = json.loads(json.dumps(meta))
    bad["tensors"][1]["offset"] = 4096
    seeds["bad_offset.mcnn"] = assemble(bad, data)
    bad = json.loads(json.dumps(meta))
    del bad["layers"][0]["kernel_h"]
    seeds["missing_field.mcnn"] = assemble(bad, data)
    bad = json.loads(json.dumps(meta))
    bad["layers"][1]["op"] = 42
    seeds["bad_enum.mcnn"] = assemble(bad, data)
    for name, blob in seeds.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(blob)
    print("make_model_corpus.py: %d seeds in %s" % (len(seeds), out))


if __name__ == "__main__":
    main()
