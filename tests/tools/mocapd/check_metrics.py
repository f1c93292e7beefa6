#!/usr/bin/python3
"""Parses mocapd's /metrics with the Prometheus client library's own parser (Debian
python3-prometheus-client) and prints, per family, its type and values as JSON: the family's
single value, or its samples by their distinguishing label. Exit 3 when the library is missing,
1 when the text does not parse."""
import json
import sys

try:
    from prometheus_client.parser import text_string_to_metric_families
except ImportError as e:  # pragma: no cover
    print(f"prometheus_client is not installed (Debian python3-prometheus-client): {e}",
          file=sys.stderr)
    sys.exit(3)

text = open(sys.argv[1], encoding="utf-8").read()
out = {}
try:
    for fam in text_string_to_metric_families(text):
        entry = {"type": fam.type, "samples": len(fam.samples)}
        if len(fam.samples) == 1:
            entry["value"] = fam.samples[0].value
        for s in fam.samples:
            for key in ("reason", "state", "queue", "kind", "camera"):
                if key in s.labels:
                    entry[s.labels[key]] = s.value
        # The family's name without _total for counters (the parser strips it).
        out[fam.name] = entry
        out[fam.name + "_total"] = entry
except Exception as e:  # the parser's error names the line
    print(f"/metrics does not parse: {e}", file=sys.stderr)
    sys.exit(1)
print(json.dumps(out))
