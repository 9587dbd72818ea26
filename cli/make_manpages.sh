#!/usr/bin/env bash
# Writes the man pages from the binary's own help: dicer(1) from
# `dicer --help` and dicer-CMD(1) from `dicer CMD --help`, so a page can
# never say something the binary does not. help2man (Debian's) does the
# roff; we only name the pages, join a usage's lines (help2man's synopsis
# is the first line only), keep the examples' lines apart (help2man fills
# every indented block into one paragraph) and give the exit codes a
# section of their own.
# Usage: make_manpages.sh DICER OUTDIR
set -euo pipefail

if [ "${1:-}" = "--joined-help" ]; then  # what help2man runs: DICER [CMD] --help
  shift
  "$@" | awk 'NR == 1 { u = $0; next }
    u != "" && /^ +[^ ]/ { l = $0; sub(/^ +/, "", l); u = u " " l; next }
    u != "" { print u; u = "" }
    { print }
    END { if (u != "") print u }'
  exit
fi

[ $# -eq 2 ] || { echo "usage: make_manpages.sh DICER OUTDIR" >&2; exit 2; }
dicer=$1 out=$2
mkdir -p "$out"
rm -f "$out"/dicer.1 "$out"/dicer-*.1  # a command since removed leaves no page behind
version=$("$dicer" --version | awk '{print $2}')
# help2man runs "PROGRAM --help" through the shell.
prog="$(printf '%q' "$BASH") $(printf '%q' "$0") --joined-help $(printf '%q' "$dicer")"

# "  name ARGS  what it does" (+ indented continuation lines) in the
# Commands section of `dicer --help`: the name and the one-line summary.
summaries=$("$dicer" --help | awk '
  /^Commands/ { on = 1; next }
  on && /^$/ { exit }
  on && /^  [a-z]/ { if (name != "") print name "\t" desc
                     name = $1; desc = $0; sub(/^  ([^ ]+ )*[^ ]+  +/, "", desc); next }
  on { line = $0; sub(/^ +/, "", line); desc = desc " " line }
  END { if (name != "") print name "\t" desc }')
[ -n "$summaries" ] || { echo "make_manpages.sh: no commands in '$dicer --help'" >&2; exit 1; }

# roff from help2man -> the page we install. help2man fills the examples
# into a paragraph (or a tagged one, where a comment is far to the right):
# the section is written again from the help, one line each, unfilled.
tidy() {  # tidy [CMD]
  "$dicer" "$@" --help </dev/null |
    awk '/^Examples:/ { on = 1; next } on && /^ / { sub(/^ +/, ""); print; next } on { exit }' |
    sed -e 's/\\/\\e/g' -e 's/-/\\-/g' -e "s/^[.']/\\\\\&&/" >"$examples"
  sed -e 's/^\.SS "Exit codes:"$/.SH "EXIT STATUS"/' |
  awk -v ex="$examples" '
    /^\.SH EXAMPLES/ { print; print ".nf"; while ((getline l < ex) > 0) print l; print ".fi"; skip = 1; next }
    skip && /^\.(SH|SS)/ { skip = 0 }
    !skip { print }'
}

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
see_also=$tmp/see_also examples=$tmp/examples
{
  echo "[SEE ALSO]"
  cut -f1 <<<"$summaries" | awk '{ printf "%s.BR dicer-%s (1)", (NR > 1 ? ",\n" : ""), $1 } END { print "" }'
} >"$see_also"
help2man --no-info --version-string "dicer $version" \
  -n "refine coarse all-hex or all-quad meshes into huge implicitly stored fine meshes" \
  --include "$see_also" "$prog" | tidy >"$out/dicer.1"

printf '[SEE ALSO]\n.BR dicer (1)\n' >"$see_also"
while IFS=$'\t' read -r name desc; do
  help2man --no-info --version-string "dicer-$name $version" -n "$desc" \
    --include "$see_also" "$prog $name" </dev/null | tidy "$name" >"$out/dicer-$name.1"
done <<<"$summaries"
