#!/usr/bin/env bash
# Installs the built dicer into a temporary prefix and checks what a user
# of the install gets besides the binary: `man dicer`, `man dicer-CMD`
# (from the help texts, cli/make_manpages.sh) and bash completion
# (cli/dicer.bash) driven through Debian's bash-completion.
set -euo pipefail
build=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
export PATH=$tmp/prefix/bin:$PATH
man1=$tmp/prefix/share/man/man1
fail() { echo "FAIL: $*" >&2; exit 1; }

# The commands README.md and `dicer --help` document.
commands="mesh-coarse sheets dice info query verify footprint export sweep transfer"

# --- man pages -------------------------------------------------------------
render() { MANWIDTH=250 man -l "$1" 2>/dev/null | sed 's/^ *//'; }
for page in dicer $(printf 'dicer-%s ' $commands); do
  f=$man1/$page.1
  [ -f "$f" ] || fail "$page.1 is not installed in $man1"
  warn=$(groff -man -Tutf8 -ww -z "$f" 2>&1)
  [ -z "$warn" ] || fail "$page.1: groff warns: $warn"
  [ "$(MANPATH=$tmp/prefix/share/man man -w "$page")" = "$f" ] || fail "man -w $page does not find $f"
done
for c in $commands; do
  text=$(render "$man1/dicer-$c.1")
  help=$(dicer "$c" --help)
  grep -q "^dicer-$c - " <<<"$text" || fail "dicer-$c(1) has no NAME line"
  # Every option the help names is in the page.
  for o in $(grep -oE -- '--[a-z][a-z0-9-]+' <<<"$help" | sort -u); do
    grep -qF -- "$o" <<<"$text" || fail "dicer-$c(1) does not mention $o"
  done
  # Every example is a line of its own, not filled into a paragraph.
  while IFS= read -r ex; do
    grep -qxF -- "$ex" <<<"$text" || fail "dicer-$c(1): the example '$ex' is not a line of its own"
  done < <(awk '/^Examples:/ { on = 1; next } on && /^ / { sub(/^ +/, ""); print }' <<<"$help")
  grep -qF "dicer(1)" <<<"$text" || fail "dicer-$c(1) does not refer to dicer(1)"
done
main=$(render "$man1/dicer.1")
grep -qx "EXIT STATUS" <<<"$main" || fail "dicer(1) has no EXIT STATUS section"
grep -qE "^143 +terminated" <<<"$main" || fail "dicer(1) does not list exit code 143"
for c in $commands; do
  grep -qF "dicer-$c(1)" <<<"$main" || fail "dicer(1) does not refer to dicer-$c(1)"
done

# --- bash completion ---------------------------------------------------------
set +eu  # bash-completion is written for interactive shells
source /usr/share/bash-completion/bash_completion
# Found the way an interactive shell finds it: on first Tab, by name, in
# XDG_DATA_DIRS (/usr/local/share:/usr/share by default).
XDG_DATA_DIRS=$tmp/prefix/share __load_completion dicer ||
  fail "bash-completion does not find dicer's completion under $tmp/prefix/share"
[[ $(complete -p dicer) == *"-F _dicer dicer" ]] || fail "complete -p dicer: $(complete -p dicer)"
# complete LINE: what pressing Tab at the end of LINE offers, one per line, sorted.
complete_line() {
  COMP_LINE=$1 COMP_POINT=${#1}
  read -ra COMP_WORDS <<<"$1"
  [[ $1 == *' ' ]] && COMP_WORDS+=('')
  COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
  COMPREPLY=()
  _dicer dicer "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD - 1]}"
  printf '%s\n' "${COMPREPLY[@]}" | sed '/^$/d' | sort
}
expect() {  # expect LINE WORD...: exactly these
  local got want
  got=$(complete_line "$1"); shift
  want=$(printf '%s\n' "$@" | sed '/^$/d' | sort)
  [ "$got" = "$want" ] || fail "completing '$line': got [$(echo $got)], want [$(echo $want)]"
}
mkdir "$tmp/work" && cd "$tmp/work" && mkdir d && touch a.msh b.e c.txt s.dice.h5 g.step plan.json
line="dicer ";                      expect "$line" $commands --help --version
line="dicer exp";                   expect "$line" export
line="dicer export s.dice.h5 --format "; expect "$line" vtkhdf msh msh-ascii exodus
line="dicer transfer s.dice.h5 s.dice.h5 --format "; expect "$line" hdf5 petsc
line="dicer dice ";                 expect "$line" a.msh b.e d
line="dicer info ";                 expect "$line" s.dice.h5 d
line="dicer dice a.msh --geometry "; expect "$line" g.step d
line="dicer mesh-coarse ";          expect "$line" g.step d
line="dicer dice a.msh --intervals-file "; expect "$line" plan.json d
line="dicer sweep s.dice.h5 --threads "; expect "$line"
line="dicer export s.dice.h5 -o ";  expect "$line" a.msh b.e c.txt d g.step plan.json s.dice.h5
for c in $commands; do
  got=$(complete_line "dicer $c x --")
  for o in $(dicer "$c" --help | grep -oE -- '^ +(-[a-z], )?--[a-z][a-z0-9-]+' | grep -oE -- '--[a-z0-9-]+' | sort -u); do
    grep -qx -- "$o" <<<"$got" || fail "completing 'dicer $c x --' does not offer $o"
  done
done
echo "man pages and bash completion: ok"
