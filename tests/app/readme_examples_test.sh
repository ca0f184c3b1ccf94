#!/usr/bin/env bash
# The command examples of README.md and docs/*.md, run as written against simulated devices: only the
# link (a serial port or an address of the reader's plant) is replaced by a simulator's; a
# simulate example serves on a pseudo-terminal in the test's folder and a port of the kernel's. An
# example that names a parameter no profile has, or writes a value the device refuses, fails
# here. Left out, with the reason: the synopsis (placeholders), scan (minutes of timeouts on a
# line that answers only some units), demo and gateway (run by their own tests), and
# examples that need the reader's own files (kiln.json, a copied profile). The AC20 restore
# example's ac20.json is a dump of the simulated AC20, made first.
# docs_references_test.py checks that every example is run by this test or another.
set -u
loopwire=$(realpath "${1:?usage: readme_examples_test.sh path/to/loopwire path/to/README.md}")
readme=${2:?usage: readme_examples_test.sh path/to/loopwire path/to/README.md}
docs=("$readme" "$(dirname "$readme")"/docs/*.md)  # the README and the pages it links
source "$(dirname "$0")/../support/test_lib.sh"

start_background sim.log timeout 90 "$loopwire" simulate --pty "$WORK_DIR/ttyR" \
  --device tc10@3 --device tc10@4 --device rampsoak@5 --device ac20@1 --unit 29 --duration 80s
wait_for_text "$WORK_DIR/sim.log" "Ctrl-C to stop"
start_tcp_server tcp.log timeout 90 "$loopwire" simulate --link tcp://127.0.0.1:0 --unit 1 --duration 80s
serial="rtu:$WORK_DIR/ttyR?parity=none"
tcp="tcp://127.0.0.1:$PORT"

# The sh blocks of the README and docs/, continuation lines joined, one command a line.
mapfile -t examples < <(awk '/^```sh/{f=1;next} /^```/{f=0} f' "${docs[@]}" | sed -e ':a' -e '/\\$/N; s/\\\n *//; ta' |
  grep -E '^loopwire (-v )?(read|write|monitor|dump|restore|decode|describe|help|simulate) ' | grep -vE ' URL |\[|DEVICE' |
  grep -vE 'kiln\.json|oven-x')
((${#examples[@]} >= 10)) || fail "found only ${#examples[@]} examples in README.md and docs/: $(printf '\n  %s' "${examples[@]}")"

cd "$WORK_DIR" || fail "no work dir"
"$loopwire" dump --link "$serial" --device ac20@1 --output ac20.json >dump.log 2>&1 || fail "cannot dump the AC20: $(cat dump.log)"
ran=0
for example in "${examples[@]}"; do
    command=${example%%#*}  # a trailing comment explains the example
    if [[ $command == "loopwire simulate "* ]]; then
        command=${command//\/tmp\/ttyV0/$WORK_DIR/ttyV0}
        command=${command//tcp:\/\/127.0.0.1:1502/tcp://127.0.0.1:0}
    else
        command=$(sed -E -e "s#--link 'rtu:[^']*'#--link '$serial'#" -e "s#--link tcp://[^ ]*#--link $tcp#" <<<"$command")
    fi
    eval "words=($command)"
    status=0
    case ${words[1]} in
        monitor)  # runs until Ctrl-C: it must still be sampling after 4 s, into its --output if it has one
            output=out.txt
            for ((i = 2; i < ${#words[@]}; i++)); do [[ ${words[i - 1]} == --output ]] && output=${words[i]}; done
            rm -f "$output"
            timeout 4 "$loopwire" "${words[@]:1}" >"out.txt" 2>&1 || status=$?
            if [[ $status -eq 124 && -s $output ]]; then status=0; fi ;;
        simulate)  # serves until Ctrl-C: it must still be serving after 5 s, having said so
            timeout 5 "$loopwire" "${words[@]:1}" >"out.txt" 2>&1 || status=$?
            if [[ $status -eq 124 ]] && grep -q "Ctrl-C to stop" out.txt; then status=0; fi ;;
        decode)  # the example frame is one whose CRC is wrong: it must say so (exit 1)
            timeout 30 "$loopwire" "${words[@]:1}" >"out.txt" 2>&1 || status=$?
            if [[ $status -eq 1 ]] && grep -q "CRC mismatch" out.txt; then status=0; fi ;;
        *) timeout 30 "$loopwire" "${words[@]:1}" >"out.txt" 2>&1 || status=$? ;;
    esac
    ran=$((ran + 1))
    if [[ $status -eq 0 ]]; then count_pass; else count_failure "README: $example (exit $status)" out.txt; fi
done
echo "ran $ran examples of README.md and docs/"
# The two CSV monitors of docs/cli.md one after the other: the second appends to what the first wrote.
mapfile -t csv_monitors < <(printf '%s\n' "${examples[@]}" | grep -E '^loopwire monitor .*--output plant\.csv')
((${#csv_monitors[@]} == 2)) || fail "expected two monitors writing plant.csv in docs/cli.md, found ${#csv_monitors[@]}"
rm -f plant.csv
for example in "${csv_monitors[@]}"; do
    command=$(sed -E -e "s#--link 'rtu:[^']*'#--link '$serial'#" <<<"${example%%#*}")
    eval "words=($command)"
    status=0
    timeout 5 "$loopwire" "${words[@]:1}" >append.out 2>&1 || status=$?
    [[ $status -eq 124 ]] || count_failure "README monitor into plant.csv (exit $status): $example" append.out
done
if [[ $(grep -c '^time' plant.csv) -eq 1 && $(wc -l <plant.csv) -ge 4 ]]; then count_pass
else count_failure readme-append-continues-the-same-csv plant.csv append.out; fi
check readme-write-took 0 "150" "$loopwire" read --link "$serial" --device tc10@3 SP
# The generic Modbus examples print what their comments say, from the words the README wrote.
check readme-float32-big 0 "12.5" "$loopwire" read --link "$tcp" --unit 1 holding 200 --type float32
check readme-float32-little 0 "12.5" "$loopwire" read --link "$tcp" --unit 1 holding 202 --type float32 --word-order little
check readme-int32-json 0 '"values":[-2]' "$loopwire" read --link "$tcp" --unit 1 holding 204 --type int32 --json
check readme-typed-write 0 '"values":[12.5,-7.75]' "$loopwire" read --link "$tcp" --unit 1 holding 300 2 --type float32 --word-order CDAB --json
check readme-reference-hex 0 "  40302  0x4148" "$loopwire" read --link "$tcp" --unit 1 40301 2 --format hex
check readme-string 0 '"values":["TC10 oven 3"]' "$loopwire" read --link "$tcp" --unit 1 holding 400 8 --type string --json
check readme-scale-base 0 "1671.2" "$loopwire" read --link "$tcp" --unit 1 holding 201 1 --type uint16 --scale 0.1 --base 1
finish
