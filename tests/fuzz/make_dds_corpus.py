#!/usr/bin/env python3
"""Writes the seeds of fuzz_dds_detections (tests/fuzz/corpus/dds_detections/).

The target reads its input through FuzzedDataProvider (integers and booleans from the end,
bytes from the front), so the seeds are byte patterns rather than samples: runs of 0x01 make
every choice take its usual branch (a well-formed sample of one topology with one candidate a
joint), other fills and a few fixed-seed random inputs take the others.

    python3 tests/fuzz/make_dds_corpus.py [OUT_DIR]
"""
import os
import random
import sys

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "corpus", "dds_detections")
os.makedirs(out, exist_ok=True)
seeds = {
    "usual_coco17_512.bin": b"\x01" * 512,
    "usual_body19_2k.bin": b"\x01" * 2047 + b"\x00",
    "usual_body25_4k.bin": b"\x01" * 4095 + b"\x02",
    "all_ff_1k.bin": b"\xff" * 1024,
    "all_zero_1k.bin": b"\x00" * 1024,
}
rng = random.Random(27)
for n in (64, 700, 3000):
    seeds[f"random_{n}.bin"] = bytes(rng.randrange(256) for _ in range(n))
for name, data in seeds.items():
    with open(os.path.join(out, name), "wb") as f:
        f.write(data)
print(f"make_dds_corpus.py: {len(seeds)} seeds in {out}")
