#!/usr/bin/env bash
# bench/bench_soak.sh - a long run against one btfd (run by bench/run.sh, which
# writes its stdout to bench/results/soak.txt): SOAK_MINUTES (default 20) of churn by
# SOAK_AGENTS (default 40) clients of bench/load/soak.mjs (connects, subscriptions
# with random budgets, budget changes, unsubscribes, TCP resets, stalled readers
# dropped by --stall-timeout), while every 30 s one of the library's packages is
# replaced underneath (compressed anew, renamed over the old one; btfd rescans every
# second). Each minute it samples btfd's resident memory, open descriptors, CPU
# seconds and bytes sent (/proc and /metrics) and prints them as a table; then the
# growth over the run after its first minute (rss_growth_kb, fd_growth), the CPU per
# GB sent, and btfd's error lines. "Flat": memory and descriptors stop growing once
# the caches are warm, and no error line.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
MINUTES=${SOAK_MINUTES:-20}
AGENTS=${SOAK_AGENTS:-40}
btf=$BUILD/btf
work=$(mktemp -d /tmp/btfsoak-XXXXXX)
pid=
cpid=
finish() {
    [[ -n $cpid ]] && kill "$cpid" 2>/dev/null
    [[ -n $pid ]] && kill "$pid" 2>/dev/null
    wait 2>/dev/null
    rm -rf "$work"
}
trap finish EXIT
lib=$work/lib
mkdir -p "$lib"
names=(knit tiles stone)
for i in 0 1 2; do
    "$btf" compress "gen:${names[$i]}:32:$((7 + i))" "$lib/${names[$i]}" --quiet --components 8 >&2
done
"$BUILD/btfd" --library "$lib" --port 0 --rescan-ms 1000 --stall-timeout 5 >"$work/btfd.out" 2>"$work/btfd.log" &
pid=$!
for _ in $(seq 50); do grep -q listening "$work/btfd.out" 2>/dev/null && break; sleep 0.1; done
port=$(sed -n 's/.*127.0.0.1:\([0-9]*\)\/.*/\1/p' "$work/btfd.out")
node bench/load/soak.mjs "$port" "$MINUTES" "$AGENTS" "${names[@]}" >"$work/client.txt" 2>&1 &
cpid=$!

sample() { # minute rss_kb fds cpu_s sent_bytes
    local rss fds cpu sent
    rss=$(awk '/^VmRSS/ {print $2}' "/proc/$pid/status")
    fds=$(find "/proc/$pid/fd" -mindepth 1 -maxdepth 1 | wc -l)
    cpu=$(awk -v hz="$(getconf CLK_TCK)" '{printf "%.2f", ($14 + $15) / hz}' "/proc/$pid/stat")
    sent=$(curl -s "http://127.0.0.1:$port/metrics" | awk '$1 == "btfd_sent_bytes_total" {printf "%.0f", $2}')
    echo "$1 $rss $fds $cpu $sent"
}
echo "# soak: $MINUTES minutes, $AGENTS agents, 3 packages (one replaced every 30 s), btfd --stall-timeout 5"
echo "# | minute | RSS kB | descriptors | CPU s | sent MB |"
echo "# |---|---|---|---|---|"
samples=()
replaced=0
start=$(date +%s)
for ((m = 1; m <= MINUTES; m++)); do
    for half in 0 1; do # on the clock: the clients' minutes are these
        at=$((start + 60 * (m - 1) + 30 * (half + 1)))
        now=$(date +%s)
        ((at > now)) && sleep $((at - now))
        n=${names[$(((2 * m + half) % 3))]}
        seed=$((100 + 2 * m + half))
        if "$btf" compress "gen:$n:32:$seed" "$lib/.new-$n" --quiet --components 8 >&2 2>/dev/null; then
            mv "$lib/$n" "$lib/.old-$n" && mv "$lib/.new-$n" "$lib/$n" && rm -rf "$lib/.old-$n"
            replaced=$((replaced + 1))
        fi
    done
    s=$(sample "$m")
    samples+=("$s")
    read -r _ rss fds cpu sent <<<"$s"
    echo "# | $m | $rss | $fds | $cpu | $(awk -v b="$sent" 'BEGIN {printf "%.1f", b / 1e6}') |"
done
wait "$cpid" || true
cpid=
read -r _ rss1 fds1 cpu1 sent1 <<<"${samples[0]}"
read -r _ rssN fdsN cpuN sentN <<<"${samples[-1]}"
echo "soak_minutes $MINUTES min"
echo "soak_packages_replaced $replaced count"
echo "soak_rss_first_kb $rss1 kB"
echo "soak_rss_last_kb $rssN kB"
echo "soak_rss_growth_kb $((rssN - rss1)) kB"
echo "soak_fd_growth $((fdsN - fds1)) count"
awk -v c1="$cpu1" -v cN="$cpuN" -v s1="$sent1" -v sN="$sentN" \
    'BEGIN {gb = (sN - s1) / 1e9; printf "soak_sent_gb %.3f GB\nsoak_cpu_s_per_gb %.2f s\n", gb, (gb > 0 ? (cN - c1) / gb : 0)}'
echo "soak_error_lines $(grep -c ' ERROR ' "$work/btfd.log" || true) count"
tail -n 1 "$work/client.txt" | grep -q soak_client_done && echo "soak_client_errors $(awk '/^minute/ {e = $NF} END {print e + 0}' "$work/client.txt") count"
grep '^minute' "$work/client.txt" | tail -n 1 | sed 's/^/# client: /'
