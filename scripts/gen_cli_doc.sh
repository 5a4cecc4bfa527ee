#!/usr/bin/env bash
# Writes the command-line reference (docs/cli.md) to stdout, from the built tool itself:
#   bash scripts/gen_cli_doc.sh BUILD_DIR > docs/cli.md
# It runs `BUILD_DIR/stylerf help` for the list of commands, then `stylerf <command> --help` for each;
# `eval` has subcommands, each with its own --help (`bench`'s --help lists its benchmarks itself).
# The CTest test cli_doc (tests/cli_doc_test.sh) fails when docs/cli.md differs from this output.
set -euo pipefail
if [ $# -ne 1 ]; then
  echo "usage: bash scripts/gen_cli_doc.sh BUILD_DIR > docs/cli.md" >&2
  exit 2
fi
S="$1/stylerf"
if [ ! -x "$S" ]; then
  echo "gen_cli_doc: no stylerf executable at $S (build it first: cmake --build $1 --target stylerf)" >&2
  exit 2
fi

# --help must not depend on the machine or the user: fixed locale, none of stylerf's variables, and a
# home folder written as "~" (default paths such as the weights folder print as ~/.cache/stylerf/...).
# It runs in an empty temporary folder, so nothing can land in the caller's.
S=$(cd "$(dirname "$S")" && pwd)/stylerf
export LC_ALL=C
unset STYLERF_DEVICE STYLERF_WEIGHTS STYLERF_CACHE_DIR STYLERF_KERNEL_DIR STYLERF_PROFILE XDG_CACHE_HOME || true
export HOME='~'
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

# One command's help, verbatim; fails when the command does not answer --help with status 0.
help_of() {
  local out
  if ! out=$("$S" "$@" --help 2>&1); then
    echo "gen_cli_doc: 'stylerf $* --help' failed:" >&2
    echo "$out" >&2
    exit 1
  fi
  # A command whose --help points to --help-all (train-style) is documented with every option.
  if grep -q -- "--help-all" <<<"$out"; then
    out=$("$S" "$@" --help-all 2>&1) || { echo "gen_cli_doc: 'stylerf $* --help-all' failed" >&2; exit 1; }
  fi
  printf '%s\n' "$out"
}

listing=$("$S" help)
# The listing's command lines: "  name   summary" under each group heading (examples are indented further).
commands=$(printf '%s\n' "$listing" | awk '/^Examples:/ {exit} /^  [a-z][a-z-]*  +[^ ]/ {print $1}')
if [ -z "$commands" ]; then
  echo "gen_cli_doc: 'stylerf help' listed no commands" >&2
  exit 1
fi

# The whole document; trailing blanks are stripped (boost pads the wrapped lines of its help).
generate() {
  echo "# stylerf command-line reference"
  echo
  echo "Generated from the tool's own help by \`bash scripts/gen_cli_doc.sh BUILD_DIR > docs/cli.md\`; do not"
  echo "edit it by hand. The CTest test \`cli_doc\` fails when this file and \`stylerf <command> --help\` differ."
  echo "What the commands are for: README.md; how they work: docs/design.md."
  echo
  echo "## Commands"
  echo
  echo '```'
  printf '%s\n' "$listing"
  echo '```'
  for c in $commands; do
    echo
    echo "## stylerf $c"
    echo
    case "$c" in
      eval)
        echo '```'
        help_of eval
        echo '```'
        subs=$(help_of eval | awk '/^subcommands:/ {on = 1; next} on && !NF {exit} on {print $1}')
        for s in $subs; do
          echo
          echo "### stylerf eval $s"
          echo
          echo '```'
          help_of eval "$s"
          echo '```'
        done
        ;;
      *)
        echo '```'
        help_of "$c"
        echo '```'
        ;;
    esac
  done
}

generate | sed 's/[[:space:]]*$//'
