#!/usr/bin/env bash
# The link graph of runtime/'s libraries (cmake/RuntimeAreas.cmake), read from the archives:
# every symbol of namespace mocap that a library's objects leave undefined must be defined in
# that library or in one it may use (directly or through the libraries it uses). Fails naming
# the object, the symbol and the library that defines it otherwise, or when no library does.
#
# usage: check_link_graph.sh NM LIBRARY=ALLOWED=ARCHIVE...   (ALLOWED: comma-separated names)
set -euo pipefail
nm_tool=$1
shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
: >"$work/defined"
: >"$work/undefined"
: >"$work/allowed"
for spec in "$@"; do
  lib=${spec%%=*}
  rest=${spec#*=}
  allowed=${rest%%=*}
  archive=${rest#*=}
  [[ -f $archive ]] || { echo "check_link_graph: $lib: no archive $archive (build it first)"; exit 2; }
  echo "$lib $allowed" >>"$work/allowed"
  # POSIX format: a member header ("archive[member.o]:" from GNU nm, "member.o:" from llvm-nm),
  # then "symbol type value size" lines.
  "$nm_tool" -P -g "$archive" | awk -v lib="$lib" -v def="$work/defined" -v undef="$work/undefined" '
    NF == 1 && /:$/ { member = $1; sub(/.*\[/, "", member); sub(/\]?:$/, "", member); next }
    $1 !~ /5mocap/ { next }
    $2 == "U" { print lib, member, $1 >> undef; next }
    $2 ~ /^[TtWVDdBbRrSsGgu]$/ { print lib, $1 >> def }'
done
awk -v allowed_file="$work/allowed" -v def_file="$work/defined" '
  BEGIN {
    while ((getline line < allowed_file) > 0) {
      split(line, f, " ")
      n = split(f[2], a, ",")
      for (i = 1; i <= n; i++) if (a[i] != "") may[f[1], a[i]] = 1
      libs[f[1]] = 1
    }
    while ((getline line < def_file) > 0) {
      split(line, f, " ")
      if (!((f[2], f[1]) in own)) { own[f[2], f[1]] = 1; owners[f[2]] = owners[f[2]] " " f[1] }
    }
  }
  {
    lib = $1; member = $2; sym = $3
    if ((sym, lib) in own) next
    if (!(sym in owners)) { print lib " (" member ") uses " sym ", which no runtime library defines"; next }
    n = split(owners[sym], o, " "); ok = 0; first = ""
    for (i = 1; i <= n; i++) { if ((lib, o[i]) in may) ok = 1; if (first == "") first = o[i] }
    if (!ok) print lib " (" member ") uses " sym ", defined in " first ", a library " lib " may not use"
  }' "$work/undefined" | sort -u >"$work/bad"
libs=$#
symbols=$(wc -l <"$work/undefined")
if ((symbols == 0)); then
  echo "check_link_graph: read no undefined mocap:: symbol from the archives ($nm_tool output not understood?)"
  exit 2
fi
if [[ -s $work/bad ]]; then
  count=$(wc -l <"$work/bad")
  # Names demangled for the reader (the check itself compares mangled names).
  head -n 40 "$work/bad" | c++filt
  echo "check_link_graph: $count uses of a library outside what cmake/RuntimeAreas.cmake allows"
  exit 1
fi
echo "check_link_graph: $libs libraries, $symbols undefined references to namespace mocap, each to" \
     "the library itself or one it may use"
