#!/usr/bin/env bash
# server/deploy/cluster.sh - nginx in front of N btfd on one read-only library (doc/deploy.md).
#
#   server/deploy/cluster.sh start LIBRARY DIR [N [PORT]]
#   server/deploy/cluster.sh stop DIR
#
# start: N btfd (default 2) on free loopback ports (--port 0) and nginx, with
# DIR as its prefix (config rendered from server/deploy/nginx.conf.in, logs,
# cache), listening on 127.0.0.1:PORT (default: a free one in 20000..49999).
# Everything runs in the background; DIR/cluster.env records NGINX_PORT,
# NGINX_PID, BTFD_PORTS and BTFD_PIDS (shell syntax, for `source`), and the
# last line printed is "cluster: http://127.0.0.1:PORT/ -> btfd 127.0.0.1:P1 ...".
# stop: SIGTERM to every process of DIR/cluster.env (btfd drains), SIGKILL
# after 15 s for what is still there.
# Environment: BTFD (default build/btfd), NGINX (default: nginx on PATH, else
# /usr/sbin/nginx), BTFD_ARGS (more btfd options, e.g. "--drain-seconds 5"),
# NGINX_PLAIN_RETRY (non-empty: no proxy_next_upstream lines, nginx's default
# "error timeout", as an operator's own configuration may have it).
# Exit status: 0 ok, 1 something did not start (what did is stopped again), 2 usage.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
BTFD=${BTFD:-build/btfd}
NGINX=${NGINX:-$(command -v nginx || echo /usr/sbin/nginx)}

usage() { sed -n '3,5p' "${BASH_SOURCE[0]}" | sed 's/^# //' >&2; exit 2; }

# start_btfd LIBRARY LOG: one btfd on a free port; sets pid and port.
start_btfd() {
    local out=$2.out
    # shellcheck disable=SC2086
    "$BTFD" --library "$1" --port 0 --bind 127.0.0.1 ${BTFD_ARGS:-} >"$out" 2>"$2" &
    pid=$!
    port=
    for _ in $(seq 100); do
        port=$(grep -so '127\.0\.0\.1:[0-9]*' "$out" | head -1 | cut -d: -f2 || true)
        [[ -n $port ]] && return 0
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.05
    done
    echo "cluster: btfd did not start: $(cat "$2")" >&2
    return 1
}

# render DIR PORT: DIR/nginx.conf from the template, upstreams from $ups.
render() {
    local user=""
    ((EUID == 0)) && user="user root root;  # as root the workers would be nobody, who cannot read DIR"
    awk -v prefix="$1" -v listen="127.0.0.1:$2" -v ups="$ups" -v user="$user" -v plain="${NGINX_PLAIN_RETRY:-}" '
        /^#/ { print; next }
        plain != "" && /proxy_next_upstream/ { next }
        { gsub(/@PREFIX@/, prefix); gsub(/@LISTEN@/, listen); gsub(/@USER@/, user) }
        /^[ \t]*@UPSTREAMS@[ \t]*$/ { printf "%s", ups; next }
        { print }' "$here/nginx.conf.in" >"$1/nginx.conf"
}

# nginx_free_port DIR RENDER [PORT]: RENDER DIR P writes DIR/nginx.conf for port P;
# tries up to 5 free-looking ports (only PORT when given) until nginx listens.
# Sets nginx_pid, nginx_port. (Also used by bench/bench_server.sh.)
nginx_free_port() {
    local d=$1 tries=5
    [[ -n ${3:-} ]] && tries=1
    for _ in $(seq $tries); do
        nginx_port=${3:-$((20000 + RANDOM % 30000))}
        "$2" "$d" "$nginx_port"
        "$NGINX" -t -q -p "$d" -c "$d/nginx.conf" -e "$d/logs/error.log" 2>>"$d/logs/start.log" || {
            echo "cluster: nginx rejects $d/nginx.conf: $(cat "$d/logs/start.log")" >&2
            return 1
        }
        "$NGINX" -p "$d" -c "$d/nginx.conf" -e "$d/logs/error.log" 2>>"$d/logs/start.log" &
        nginx_pid=$!
        for _ in $(seq 60); do
            if (exec 3<>"/dev/tcp/127.0.0.1/$nginx_port") 2>/dev/null; then return 0; fi
            kill -0 "$nginx_pid" 2>/dev/null || break
            sleep 0.05
        done
        kill "$nginx_pid" 2>/dev/null || true
        wait "$nginx_pid" 2>/dev/null || true
    done
    echo "cluster: nginx did not start: $(cat "$d/logs/error.log" "$d/logs/start.log" 2>/dev/null)" >&2
    return 1
}

stop() {
    local env=$1/cluster.env
    [[ -f $env ]] || { echo "cluster: no $env" >&2; return 1; }
    # shellcheck disable=SC1090
    source "$env"
    local all=("${BTFD_PIDS[@]}" "$NGINX_PID")
    for p in "${all[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
    for _ in $(seq 150); do
        local alive=0
        for p in "${all[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
        ((alive)) || return 0
        sleep 0.1
    done
    for p in "${all[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
}

start() {
    local lib=$1 d=$2 n=${3:-2} want=${4:-}
    [[ -d $lib ]] || { echo "cluster: $lib is not a directory" >&2; return 1; }
    mkdir -p "$d"
    d=$(cd "$d" && pwd)
    local pids=() ports=() ups="" i
    for ((i = 0; i < n; i++)); do
        if ! start_btfd "$lib" "$d/btfd-$i.log"; then
            for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
            return 1
        fi
        pids+=("$pid")
        ports+=("$port")
        ups+="        server 127.0.0.1:$port max_fails=1 fail_timeout=10s;"$'\n'
    done
    mkdir -p "$d/logs" "$d/tmp" "$d/cache"
    if ! nginx_free_port "$d" render "$want"; then
        for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
        return 1
    fi
    {
        echo "NGINX_PORT=$nginx_port"
        echo "NGINX_PID=$nginx_pid"
        echo "BTFD_PORTS=(${ports[*]})"
        echo "BTFD_PIDS=(${pids[*]})"
    } >"$d/cluster.env"
    echo "cluster: http://127.0.0.1:$nginx_port/ -> btfd$(printf ' 127.0.0.1:%s' "${ports[@]}")"
}

[[ ${BASH_SOURCE[0]} != "$0" ]] && return 0 # sourced: the functions only

case ${1:-} in
start) (($# >= 3 && $# <= 5)) || usage; start "$2" "$3" "${4:-2}" "${5:-}" ;;
stop) (($# == 2)) || usage; stop "$2" ;;
*) usage ;;
esac
