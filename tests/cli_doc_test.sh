#!/usr/bin/env bash
# CTest cli_doc: docs/cli.md must be what scripts/gen_cli_doc.sh makes from the built tool's --help.
#   bash tests/cli_doc_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
BUILD_DIR=$1
SRC=$2
tmp=$(mktemp)
trap 'rm -f "$tmp"' EXIT
bash "$SRC/scripts/gen_cli_doc.sh" "$BUILD_DIR" > "$tmp"
if ! diff -u "$SRC/docs/cli.md" "$tmp"; then
  echo
  echo "docs/cli.md is out of date with the commands' --help (the diff above: - the file, + the tool)."
  echo "Regenerate it and commit the result:"
  echo "  bash scripts/gen_cli_doc.sh $BUILD_DIR > docs/cli.md"
  exit 1
fi
echo "docs/cli.md matches every command's --help"
