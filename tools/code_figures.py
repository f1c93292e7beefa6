#!/usr/bin/env python3
"""Structure figures of the source tree (issue 39's before/after table): lines in tools/mocapd,
data members of mocapd's Daemon, functions over 100 lines, string comparisons of states, and
(where the `duplicates` tool is installed) pairs of places sharing six or more lines.

usage: tools/code_figures.py [ROOT]   (ROOT: a checkout; default: this one)
Functions are found by brace matching at namespace/class scope: a heuristic, the same for
every tree it is run on, so before/after figures compare.
"""
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                       os.path.join(os.path.dirname(__file__), '..'))
SOURCE_DIRS = ('runtime', 'tools', 'hal')
STATES = ('recording|complete|stopped|interrupted|unreadable|simulator|replay|cameras|fusion|'
          'ok|missing|invalid|mismatch|calibrating')
STATE_COMPARE = re.compile(r'(==|!=)\s*"(%s)"|\.find\("(calibrating from|have no calibration|'
                           r'no calibration yet)' % STATES)


def sources(exts=('.cpp', '.h')):
    for d in SOURCE_DIRS:
        for dirpath, _, files in os.walk(os.path.join(ROOT, d)):
            for f in files:
                if f.endswith(exts):
                    yield os.path.join(dirpath, f)


def strip_code(text):
    """Comments, strings and chars blanked (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith('//', i):
            j = text.find('\n', i)
            i = n if j < 0 else j
        elif text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append('\n' * text.count('\n', i, j))
            i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            end = text.find(')' + (m.group(1) if m else '') + '"', i)
            j = n if end < 0 else end + len(m.group(1) if m else '') + 2
            out.append('""' + '\n' * text.count('\n', i, j))
            i = j
        elif c in '"\'':
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == '\\' else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return ''.join(out)


def long_functions(path, limit=100):
    code = strip_code(open(path, encoding='utf-8', errors='replace').read())
    found, stack, head_start, line = [], [], 0, 1
    for i, c in enumerate(code):
        if c == '\n':
            line += 1
        elif c == '{':
            head = code[head_start:i]
            outer = all(kind in ('namespace', 'class') for kind, _, _ in stack)
            if re.search(r'\bnamespace\b', head) or (re.search(r'\b(class|struct|union)\b', head)
                                                     and '(' not in head):
                kind = 'namespace' if 'namespace' in head else 'class'
            elif outer and ')' in head and not re.search(r'=\s*$', head):
                kind = 'function'
            else:
                kind = 'block'
            name = re.findall(r'([\w:~]+)\s*\(', head)
            stack.append((kind, line, name[0] if name else '?'))
            head_start = i + 1
        elif c == '}':
            if stack:
                kind, start, name = stack.pop()
                if kind == 'function' and line - start + 1 > limit:
                    found.append((os.path.relpath(path, ROOT), start, line - start + 1, name))
            head_start = i + 1
        elif c == ';':
            head_start = i + 1
    return found


def daemon_members():
    path = os.path.join(ROOT, 'tools/mocapd/daemon.h')
    code = strip_code(open(path).read())
    body = code[code.index('class Daemon {'):]
    # Data members: declarations at class depth ending in `name_` (this code's convention).
    depth, members = 0, 0
    text = ''
    for c in body:
        if c == '{':
            depth += 1
        elif c == '}':
            depth -= 1
            if depth == 0:
                break
        elif c == ';' and depth == 1:
            if re.search(r'\b\w+_\s*(\{[^}]*\}|=[^;]*)?\s*$', text) and '(' not in text.split('=')[0]:
                members += 1
            text = ''
            continue
        if depth == 1:
            text += c
    return members


def main():
    mocapd = [p for p in sources() if '/tools/mocapd/' in p]
    print('mocapd_lines=%d' % sum(sum(1 for _ in open(p)) for p in mocapd))
    print('daemon_members=%d' % daemon_members())
    longs = [f for p in sources(('.cpp',)) for f in long_functions(p)]
    print('functions_over_100_lines=%d' % len(longs))
    for f in sorted(longs):
        print('  %s:%d %d lines %s' % f)
    compares = []
    for p in sources():
        for n, l in enumerate(open(p, encoding='utf-8', errors='replace'), 1):
            if STATE_COMPARE.search(l) and not l.lstrip().startswith('//'):
                compares.append('%s:%d' % (os.path.relpath(p, ROOT), n))
    print('state_string_compares=%d' % len(compares))
    for c in compares:
        print('  ' + c)
    if shutil.which('duplicates'):
        out = subprocess.run(['duplicates', '--repo', ROOT, '--seconds', '120', '--most', '1'],
                             capture_output=True, text=True).stdout.splitlines()
        print('duplicates: ' + (out[0] if out else '(no answer)'))


if __name__ == '__main__':
    main()
