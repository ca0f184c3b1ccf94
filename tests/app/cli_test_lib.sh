# Shared by the CLI test scripts: a scratch directory removed at exit with every background
# process started into `pids`, and check(), which runs a command with a time limit and compares
# its exit status and output.
work=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; wait 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
failures=0
passes=0

check() {  # name, expected-status, expected-substring (stdout+stderr), command...
  local name=$1 want=$2 text=$3; shift 3
  local out status
  out=$(timeout 20 "$@" 2>&1); status=$?
  if [ "$status" -ne "$want" ] || [[ "$out" != *"$text"* ]]; then
    echo "FAIL $name: status $status (want $want), output:"; echo "$out" | sed 's/^/    /'
    echo "    (wanted text: $text)"
    failures=$((failures + 1))
  else
    passes=$((passes + 1))
  fi
}

wait_for_path() { for _ in $(seq 100); do [ -e "$1" ] && return 0; sleep 0.05; done; return 1; }

finish() {  # prints the tally; exits non-zero on any failure
  echo "$passes passed, $failures failed"
  [ "$failures" -eq 0 ]
}
