#!/usr/bin/env python3
"""The page's import map is allowed by its hash in mocapd's content security policy
(tools/mocapd/web.cpp, kPagePolicy): fails naming the hash to put there when index.html's
import map changed without it.  usage: check_csp_hash.py SOURCE_DIR"""
import base64
import hashlib
import re
import sys

root = sys.argv[1]
html = open(f"{root}/tools/web/page/index.html", encoding="utf-8").read()
inline = re.findall(r"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", html, re.S)
policy = open(f"{root}/tools/mocapd/web.cpp", encoding="utf-8").read()
bad = 0
for text in inline:
    digest = base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode()
    if f"'sha256-{digest}'" not in policy:
        print(f"index.html has an inline script whose hash 'sha256-{digest}' is not in "
              "tools/mocapd/web.cpp's kPagePolicy: put it there (the browser refuses the script)")
        bad += 1
if re.search(r"\sstyle=|\son[a-z]+=", html):
    print("index.html has an inline style or event attribute: the policy refuses it; use style.css / app.js")
    bad += 1
print(f"check_csp_hash: {len(inline)} inline scripts, {bad} problems")
sys.exit(1 if bad else 0)
