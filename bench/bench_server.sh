#!/usr/bin/env bash
# bench/bench_server.sh - btfd against nginx on loopback (run by bench/run.sh,
# which writes its stdout to bench/results/server.txt).
#
#   BUILD=build bash bench/bench_server.sh
#
# Builds bench/load/server_load.c (libwebsockets + cJSON client, epoll HTTP client)
# into $BUILD/bench/server_load, generates one package once
# ($BUILD/bench/server-lib/knit: `btf compress gen:knit:128`, 8 chunks,
# about 1.9 MB), then for 1, 100 and 1000 concurrent clients:
#   - btfd (fresh process per run): every client subscribes over one
#     WebSocket and streams the whole package;
#   - nginx (Debian package, fresh process per run, temp config and prefix
#     under /tmp, worker_processes 1 like btfd's single thread, sendfile on):
#     every client GETs manifest.json and then every file in manifest order
#     over one keep-alive connection: the same bytes.
# Per run: aggregate MB/s, time to first chunk (connect start -> chunk 0
# complete: median, p99), server peak RSS (VmHWM of /proc/PID/status, summed
# over nginx's master and worker) and server CPU seconds (utime + stime).
# Then 200 clients that stop reading (lws_rx_flow_control) next to 100 normal
# ones: btfd's peak RSS and the normal clients' throughput against a run
# without the stalled ones.
# Then the deployment of doc/deploy.md (server/deploy/cluster.sh: nginx,
# worker_processes auto, in front of 2 btfd on the same library), 1000 clients:
#   - cluster_ws: every client streams the package over a WebSocket through
#     nginx (compared with btfd_c1000, one btfd direct);
#   - cluster_http: every client GETs the immutable package URLs
#     (/materials/knit/ETAG/FILE) that nginx serves from its proxy_cache
#     (warmed by one client first, so the btfd see almost nothing).
#   Per run: MB/s, time to first chunk, btfd and nginx CPU seconds, server
#   CPU per GB (btfd + nginx).
# Every run also reports the load generator's CPU use (NAME_client_cpu_pct,
# its CPU seconds over the run's wall time; near 100 % it is the bottleneck).
# SECTIONS (default "direct stall cluster") picks parts: direct = the 1/100/1000
# client runs (DIRECT_CLIENTS, default "1 100 1000"), stall = the stalled
# clients, cluster = nginx + 2 btfd (its ratios need btfd_c1000 of direct).
# Loopback only (127.0.0.1); every server is stopped on exit, also on error.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

BUILD=${BUILD:-build}
CC=${CC:-cc}
btfd=$BUILD/btfd
btf=$BUILD/btf
nginx_bin=$(command -v nginx || echo /usr/sbin/nginx)
for f in "$btfd" "$btf"; do
    [[ -x $f ]] || { echo "bench_server: $f is missing: run 'make build' first" >&2; exit 1; }
done
[[ -x $nginx_bin ]] || { echo "bench_server: nginx is not installed (make setup installs nginx-light)" >&2; exit 1; }

hard=$(ulimit -Hn)
ulimit -n $((hard < 20000 ? hard : 20000))
if (($(ulimit -n) < 2200)); then
    echo "bench_server: need 2200 file descriptors, have $(ulimit -n)" >&2
    exit 1
fi

work=$(mktemp -d /tmp/btfbench-XXXXXX)
pids=()
SECTIONS=${SECTIONS:-direct stall cluster}
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
    for d in "$work"/cluster-*; do [[ -f $d/cluster.env ]] && server/deploy/cluster.sh stop "$d" >/dev/null 2>&1; done
    rm -rf "$work"
}
trap cleanup EXIT

# ---------------------------------------------------------------- client and data
load=$BUILD/bench/server_load
mkdir -p "$BUILD/bench"
echo "bench_server: building $load" >&2
# shellcheck disable=SC2046
$CC -std=c11 -Wall -Wextra -Werror -O2 -g -D_GNU_SOURCE -Itests $(pkg-config --cflags libwebsockets libcjson) \
    -o "$load" bench/load/server_load.c $(pkg-config --libs libwebsockets libcjson)

lib=$BUILD/bench/server-lib
mat=knit
if [[ ! -f $lib/$mat/manifest.json ]]; then
    echo "bench_server: generating $lib/$mat (btf compress gen:knit:128, about a minute)" >&2
    mkdir -p "$lib"
    "$btf" compress gen:knit:128 "$lib/$mat" --quiet >&2
fi
lib=$(cd "$lib" && pwd) # nginx resolves a relative root against its prefix
pkg_bytes=$(du -cb "$lib/$mat"/* | awk '/total/ {print $1}')
echo "package_bytes $pkg_bytes B"
echo "package_chunks $(grep -o '"files"' "$lib/$mat/manifest.json" | wc -l) chunks"

# ---------------------------------------------------------------- helpers
NGINX=$nginx_bin
# shellcheck source=server/deploy/cluster.sh
source server/deploy/cluster.sh # nginx_free_port (and the cluster's start/stop)
clk=$(getconf CLK_TCK)
cpu_s() { awk -v t="$clk" '{printf "%.3f", ($14 + $15) / t}' "/proc/$1/stat"; }
hwm_kb() { awk '/VmHWM/ {print $2}' "/proc/$1/status"; }

start_btfd() { # sets srv_pid, port
    mkdir -p "$work/empty"
    rm -f "$work/btfd.out"
    "$btfd" --library "$lib" --port 0 --rescan-ms 0 --client "$work/empty" --shaders "$work/empty" \
        >"$work/btfd.out" 2>>"$work/btfd.err" &
    srv_pid=$!
    pids+=("$srv_pid")
    for _ in $(seq 100); do
        # the job may not have created the file yet: never read an old port
        port=$(grep -so '127\.0\.0\.1:[0-9]*' "$work/btfd.out" | cut -d: -f2 || true)
        [[ -n $port ]] && return 0
        sleep 0.05
    done
    echo "bench_server: btfd did not start: $(cat "$work/btfd.err")" >&2
    exit 1
}

# render_static DIR PORT: DIR/nginx.conf of the static-file nginx (root $lib).
render_static() {
    cat >"$1/nginx.conf" <<EOF
daemon off;
$( ((EUID == 0)) && echo "user root root;  # as root, workers would be nobody, who cannot read \$lib")
worker_processes 1;
worker_rlimit_nofile 8192;
pid $1/nginx.pid;
error_log $1/logs/error.log error;
events { worker_connections 4096; multi_accept on; }
http {
    access_log off;
    sendfile on;
    tcp_nopush on;
    tcp_nodelay on;
    keepalive_requests 100000;
    keepalive_timeout 60s;
    client_body_temp_path $1/tmp/body;
    proxy_temp_path $1/tmp/proxy;
    fastcgi_temp_path $1/tmp/fastcgi;
    uwsgi_temp_path $1/tmp/uwsgi;
    scgi_temp_path $1/tmp/scgi;
    types { application/json json; image/png png; application/octet-stream bin; }
    default_type application/octet-stream;
    server {
        listen 127.0.0.1:$2 backlog=4096;
        root $lib;
    }
}
EOF
}

start_nginx() { # sets srv_pid, port
    local d=$work/nginx
    mkdir -p "$d/logs" "$d/tmp"
    nginx_free_port "$d" render_static || exit 1
    srv_pid=$nginx_pid
    port=$nginx_port
    pids+=("$srv_pid")
}

stop_server() {
    kill "$srv_pid" 2>/dev/null || true
    wait "$srv_pid" 2>/dev/null || true
}

# nginx's processes: the master and its workers
nginx_pids() { echo "$srv_pid" $(pgrep -P "$srv_pid" || true); }

# run NAME KIND CLIENTS [STALLED]: one fresh server, one load run; its lines
# go to stdout and to $work/all.txt (for the ratios below)
run() {
    local name=$1 kind=$2 n=$3 stalled=${4:-0}
    local out=$work/$name.txt
    if [[ $kind == btfd ]]; then start_btfd; else start_nginx; sleep 0.2; fi
    local ps=$srv_pid
    [[ $kind == nginx ]] && ps=$(nginx_pids)
    local c0=0 c1=0 h=0 p
    for p in $ps; do c0=$(awk -v a="$c0" -v b="$(cpu_s "$p")" 'BEGIN {print a + b}'); done
    echo "bench_server: $name: $kind, $n clients, $stalled stalled" >&2
    if [[ $kind == btfd ]]; then
        "$load" ws "$port" "$mat" "$n" "$stalled" "${name}_" >"$out"
    else
        "$load" http "$port" "$mat" "$n" "${name}_" >"$out"
    fi
    for p in $ps; do
        c1=$(awk -v a="$c1" -v b="$(cpu_s "$p")" 'BEGIN {print a + b}')
        h=$((h + $(hwm_kb "$p")))
    done
    stop_server
    awk -v a="$c0" -v b="$c1" -v n="${name}_server_cpu" 'BEGIN {printf "%s %.2f s\n", n, b - a}' >>"$out"
    awk -v h="$h" -v n="${name}_server_peak_rss" 'BEGIN {printf "%s %.1f MB\n", n, h / 1024}' >>"$out"
    client_pct "$out" "$name"
    cat "$out"
    cat "$out" >>"$work/all.txt"
}

# client_pct FILE NAME: appends NAME_client_cpu_pct (load generator CPU / wall time).
client_pct() {
    awk -v n="$2" '$1 == n "_client_cpu" {c = $2} $1 == n "_seconds" {s = $2}
        END {if (s > 0) printf "%s_client_cpu_pct %.0f %%\n", n, 100 * c / s}' "$1" >>"$1"
}

sum_cpu() { local t=0 p; for p in "$@"; do t=$(awk -v a="$t" -v b="$(cpu_s "$p" 2>/dev/null || echo 0)" 'BEGIN {print a + b}'); done; echo "$t"; }

# cluster_run NAME ws|http CLIENTS: a fresh nginx + 2 btfd (server/deploy/cluster.sh), one load run.
cluster_run() {
    local name=$1 kind=$2 n=$3 d=$work/cluster-$1 out=$work/$1.txt
    mkdir -p "$work/empty"
    BTFD=$btfd BTFD_ARGS="--rescan-ms 0 --client $work/empty --shaders $work/empty" \
        server/deploy/cluster.sh start "$lib" "$d" 2 >&2 || exit 1
    # shellcheck disable=SC1091
    source "$d/cluster.env"
    local ng=("$NGINX_PID" $(pgrep -P "$NGINX_PID" || true))
    local etag
    etag=$(sed -n 's/.*"etag":"\([0-9a-f]\{16\}\)".*/\1/p' <(curl -s "http://127.0.0.1:$NGINX_PORT/materials"))
    [[ $kind == http ]] && "$load" http "$NGINX_PORT" "materials/$mat/$etag" 1 warm_ >/dev/null
    local b0 n0 b1 n1
    b0=$(sum_cpu "${BTFD_PIDS[@]}")
    n0=$(sum_cpu "${ng[@]}")
    echo "bench_server: $name: nginx + 2 btfd, $kind, $n clients" >&2
    if [[ $kind == ws ]]; then
        "$load" ws "$NGINX_PORT" "$mat" "$n" 0 "${name}_" >"$out"
    else
        "$load" http "$NGINX_PORT" "materials/$mat/$etag" "$n" "${name}_" >"$out"
    fi
    b1=$(sum_cpu "${BTFD_PIDS[@]}")
    n1=$(sum_cpu "${ng[@]}")
    server/deploy/cluster.sh stop "$d" >&2
    awk -v a="$b0" -v b="$b1" -v c="$n0" -v e="$n1" -v t="$((n * pkg_bytes))" -v n="$name" 'BEGIN {
        printf "%s_btfd_cpu %.2f s\n%s_nginx_cpu %.2f s\n", n, b - a, n, e - c
        printf "%s_server_cpu_per_gb %.2f s/GB\n", n, (b - a + e - c) / (t / 1e9) }' >>"$out"
    client_pct "$out" "$name"
    cat "$out"
    cat "$out" >>"$work/all.txt"
}

val() { awk -v k="$1" '$1 == k {print $2; exit}' "$work/all.txt"; }

# ---------------------------------------------------------------- runs
: >"$work/all.txt"
has() { [[ " $SECTIONS " == *" $1 "* ]]; }
has direct && for n in ${DIRECT_CLIENTS:-1 100 1000}; do
    run "btfd_c$n" btfd "$n"
    run "nginx_c$n" nginx "$n"
    b=$(val "btfd_c${n}_throughput")
    g=$(val "nginx_c${n}_throughput")
    bc=$(val "btfd_c${n}_server_cpu")
    gc=$(val "nginx_c${n}_server_cpu")
    awk -v b="$b" -v g="$g" -v n="ratio_c${n}_throughput_btfd_over_nginx" 'BEGIN {printf "%s %.2f x\n", n, b / g}'
    total=$((n * pkg_bytes))
    awk -v c="$bc" -v t="$total" -v n="btfd_c${n}_server_cpu_per_gb" 'BEGIN {printf "%s %.2f s/GB\n", n, c / (t / 1e9)}'
    awk -v c="$gc" -v t="$total" -v n="nginx_c${n}_server_cpu_per_gb" 'BEGIN {printf "%s %.2f s/GB\n", n, c / (t / 1e9)}'
done

# 200 clients that stop reading next to 100 normal ones
stall() {
    run stall_base btfd 100 0
    run stall_200 btfd 100 200
    b0=$(val stall_base_throughput)
    b1=$(val stall_200_throughput)
    r0=$(val stall_base_server_peak_rss)
    r1=$(val stall_200_server_peak_rss)
    awk -v a="$b0" -v b="$b1" 'BEGIN {printf "stall_throughput_kept %.2f x\n", b / a}'
    awk -v a="$r0" -v b="$r1" 'BEGIN {printf "stall_rss_per_stalled_client %.1f KB\n", (b - a) * 1024 / 200}'
}
has stall && stall

# nginx + 2 btfd (doc/deploy.md): WebSocket through nginx, package files from nginx's cache
if has cluster; then
    cluster_run cluster_ws ws 1000
    cluster_run cluster_http http 1000
    d=$(val btfd_c1000_throughput)
    if [[ -n $d ]]; then
        awk -v c="$(val cluster_ws_throughput)" -v d="$d" 'BEGIN {printf "ratio_cluster_ws_over_btfd_direct_throughput %.2f x\n", c / d}'
        awk -v c="$(val cluster_ws_ttfc_median)" -v d="$(val btfd_c1000_ttfc_median)" 'BEGIN {printf "ratio_cluster_ws_over_btfd_direct_ttfc_median %.2f x\n", c / d}'
    fi
    awk -v c="$(val cluster_http_throughput)" -v w="$(val cluster_ws_throughput)" 'BEGIN {printf "ratio_cluster_http_cache_over_cluster_ws_throughput %.2f x\n", c / w}'
fi
