#!/usr/bin/env bash
# docs_references_test.py must fail on what it exists to catch, each on a copy of the
# documentation broken in one way: a command that does not exist, a link to no file, an anchor
# no heading has, and an example no test runs. The untouched copy passes.
#   docs_references_catch_test.sh LOOPWIRE SOURCE_DIR
set -u
loopwire=${1:?usage: docs_references_catch_test.sh LOOPWIRE SOURCE_DIR} source_dir=${2:?}
source "$(dirname "$0")/../support/test_lib.sh"
checker=$(dirname "$0")/docs_references_test.py

# copy_tree NAME: WORK_DIR/NAME, printed: a copy of README.md and docs/, and the rest of the
# source tree linked (what the links name).
copy_tree() {
    local tree=$WORK_DIR/$1 entry
    mkdir -p "$tree" && cp -r "$source_dir/README.md" "$source_dir/docs" "$tree/"
    for entry in "$source_dir"/*; do
        [[ -e $tree/$(basename "$entry") ]] || ln -s "$(realpath "$entry")" "$tree/"
    done
    echo "$tree"
}

tree=$(copy_tree intact)
check intact-copy-passes 0 "0 failure(s)" /usr/bin/python3 "$checker" "$loopwire" "$tree"

tree=$(copy_tree command)
printf '\nSaved views are listed by `loopwire profiles --json`.\n' >>"$tree/docs/cli.md"
check catches-a-command-that-does-not-exist 1 '`loopwire profiles` names no command' \
  /usr/bin/python3 "$checker" "$loopwire" "$tree"

tree=$(copy_tree file)
printf '\nSee [the tuning guide](tuning.md).\n' >>"$tree/docs/cli.md"
check catches-a-link-to-no-file 1 "link to tuning.md: no such file or folder" /usr/bin/python3 "$checker" "$loopwire" "$tree"

tree=$(copy_tree anchor)
printf '\nSee [the exit codes](docs/cli.md#exit-codes).\n' >>"$tree/README.md"
check catches-an-anchor-no-heading-has 1 "link to docs/cli.md#exit-codes: cli.md has no heading with that anchor" \
  /usr/bin/python3 "$checker" "$loopwire" "$tree"

tree=$(copy_tree example)
printf '\n```sh\nloopwire gateway --config mine.toml\n```\n' >>"$tree/docs/gateway-configuration.md"
check catches-an-example-no-test-runs 1 'no test runs `loopwire gateway --config mine.toml`' \
  /usr/bin/python3 "$checker" "$loopwire" "$tree"
finish
