#!/usr/bin/env bash
# tests/deploy_test.sh - the two-server deployment of doc/deploy.md, for real (run by `make test`).
#
#   BUILD=build bash tests/deploy_test.sh
#
# Starts nginx (server/deploy/nginx.conf.in, its own prefix in a temp dir) in
# front of two btfd on one library (a package made by `btf compress
# gen:knit:16`) with server/deploy/cluster.sh, all on 127.0.0.1, and checks:
# health and list through nginx, package files cached by nginx (MISS, then
# HIT, byte-exact, immutable headers, ranges), and 200 WebSocket clients
# ($BUILD/resume_clients) that must all complete, every chunk once, while one
# btfd is killed (SIGKILL) in the middle, and again while one drains (SIGTERM,
# clients get 1001), and once more (SIGKILL) on a version-4 package with lossless
# WebP textures. Prints one line per check and last
# "deploy: N passed, M failed"; exits 1 when a check failed. Everything it
# started is killed on exit.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
btf=$BUILD/btf
clients=$BUILD/resume_clients
export BTFD=$BUILD/btfd
pass=0
fail=0

check() { # check NAME COMMAND...: one line, counted
    local name=$1
    shift
    if "$@" >>"$work/check.log" 2>&1; then
        pass=$((pass + 1))
        echo "deploy: ok   $name"
    else
        fail=$((fail + 1))
        echo "deploy: FAIL $name (see below)"
        tail -n 20 "$work/check.log" | sed 's/^/    /'
    fi
}

finish() {
    for d in "$work"/cluster-*; do
        [[ -f $d/cluster.env ]] || continue
        # shellcheck disable=SC1091
        (source "$d/cluster.env"; kill -KILL "${BTFD_PIDS[@]}" "$NGINX_PID" 2>/dev/null) || true
    done
    [[ -n ${hpid:-} ]] && kill -KILL "$hpid" 2>/dev/null
    [[ -n ${ppid_nginx:-} ]] && kill -KILL "$ppid_nginx" "$ppid_btfd" 2>/dev/null
    wait 2>/dev/null
    rm -rf "$work"
}

work=$(mktemp -d /tmp/btfdeploy-XXXXXX)
trap finish EXIT
for f in "$btf" "$BTFD" "$clients"; do
    [[ -x $f ]] || { echo "deploy: $f is missing: run 'make build'"; echo "deploy: 0 passed, 1 failed"; exit 1; }
done
if ! command -v nginx >/dev/null && [[ ! -x /usr/sbin/nginx ]]; then
    echo "deploy: nginx is not installed (make setup installs nginx-light)"
    echo "deploy: 0 passed, 1 failed"
    exit 1
fi
ulimit -n "$(ulimit -Hn)" 2>/dev/null || true

lib=$work/lib
mkdir -p "$lib"
check "library: btf compress gen:knit:16" "$btf" compress gen:knit:16 "$lib/knit" --quiet
etag=
base=
up() { # up NAME [LIB]: a fresh cluster; sets port, pids, base
    local d=$work/cluster-$1
    server/deploy/cluster.sh start "${2:-$lib}" "$d" 2 >>"$work/check.log" 2>&1 || return 1
    # shellcheck disable=SC1091
    source "$d/cluster.env"
    port=$NGINX_PORT
    pids=("${BTFD_PIDS[@]}")
}
get() { curl -s --max-time 10 "$@"; }

list_names_files() {
    local body
    body=$(get "http://127.0.0.1:$port/materials") || return 1
    base=$(sed -n 's/.*"files":"\([^"]*\)".*/\1/p' <<<"$body")
    etag=$(sed -n 's/.*"etag":"\([0-9a-f]\{16\}\)".*/\1/p' <<<"$body")
    [[ $base == /materials/knit/$etag/ ]]
}
health_ok() { [[ $(get -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/healthz") == 200 ]]; }
# wt J: component J's weights file in the knit package (wt-0J.z, wt-0J.pz or wt-0J.webp,
# whichever the writer kept: doc/package-format.md sections 5.4 and 5.5); empty when none
wt() { (cd "$lib/knit" || exit; compgen -G "wt-0$1.*z"; compgen -G "wt-0$1.webp"; true) | head -1; }
cache_status() { get -o "$work/got" -D - "http://127.0.0.1:$port$base$1" | tr -d '\r' | sed -n 's/^X-Cache-Status: //ip'; }
miss_then_hit() {
    local w
    w=$(wt 1)
    [[ -n $w && $(cache_status "$w") == MISS ]] && cmp "$work/got" "$lib/knit/$w" &&
        [[ $(cache_status "$w") == HIT ]] && cmp "$work/got" "$lib/knit/$w"
}
immutable_headers() {
    local h
    h=$(get -o /dev/null -D - "http://127.0.0.1:$port${base}manifest.json" | tr -d '\r')
    grep -qi '^cache-control: public, max-age=31536000, immutable$' <<<"$h" &&
        grep -qi "^etag: \"$etag-manifest.json\"$" <<<"$h"
}
range_ok() {
    local w
    w=$(wt 2)
    [[ -n $w && $(get -o "$work/range" -w '%{http_code}' -H 'Range: bytes=100-1099' "http://127.0.0.1:$port${base}$w") == 206 ]] &&
        cmp "$work/range" <(tail -c +101 "$lib/knit/$w" | head -c 1000)
}
bundle_gzip() { # the .gz make build writes beside it, as it is; the file itself without Accept-Encoding
    local h
    h=$(get -o "$work/bundle.gz" -D - -H 'Accept-Encoding: gzip, deflate, br' "http://127.0.0.1:$port/btf-viewer.js" |
        tr -d '\r') || return 1
    grep -qi '^content-encoding: gzip$' <<<"$h" && grep -qi '^vary:.*accept-encoding' <<<"$h" &&
        cmp "$work/bundle.gz" "$BUILD/client/btf-viewer.js.gz" &&
        get -o "$work/bundle.js" "http://127.0.0.1:$port/btf-viewer.js" && cmp "$work/bundle.js" "$BUILD/client/btf-viewer.js"
}
cached_after_kill() { [[ -n $(wt 1) && $(cache_status "$(wt 1)") == HIT ]] && cmp "$work/got" "$lib/knit/$(wt 1)"; }
old_etag_404() { [[ $(get -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/materials/knit/0123456789abcdef/wt-01.z") == 404 ]]; }
# failover SIG [MATERIAL LIB]: 200 clients, one btfd gets SIG once 40% of the chunks have arrived
failover() {
    local out=$work/clients-$1${2:+-$2}.txt
    timeout 100 "$clients" "$port" "${2:-knit}" "${3:-$lib}" 200 "${pids[0]}" 0.4 30 "$1" >"$out" || { cat "$out"; return 1; }
    cat "$out"
    [[ $(awk '$1 == "clients_resumed" {print $2}' "$out") -gt 0 ]]
}
has_webp() { compgen -G "$1/*.webp" >/dev/null; }
goaway_seen() { [[ $(awk '$1 == "goaway_1001" {print $2}' "$work/clients-TERM.txt") -gt 0 ]]; }
drained_exit() { # the drained btfd ends by itself, exit status 0
    for _ in $(seq 150); do kill -0 "${pids[0]}" 2>/dev/null || break; sleep 0.1; done
    ! kill -0 "${pids[0]}" 2>/dev/null && grep -q 'draining' "$work/cluster-b/btfd-0.log"
}

export BTFD_ARGS="--client $(realpath "$BUILD/client")" # the bundle make build writes
check "cluster: nginx + 2 btfd start" up a
unset BTFD_ARGS
check "health through nginx" health_ok
check "list through nginx names the immutable files base" list_names_files
check "package file: MISS then HIT from nginx's cache, byte-exact" miss_then_hit
check "immutable Cache-Control and strong ETag through nginx" immutable_headers
check "byte range through nginx: 206, right bytes" range_ok
check "the client bundle through nginx: gzipped for a browser that accepts it, else itself" bundle_gzip
check "unknown etag: 404" old_etag_404
check "200 clients, one btfd SIGKILLed mid-way: all complete, none twice, resumed" failover KILL
check "package file still served by the cache after the kill" cached_after_kill
check "btfd logs the client address nginx forwards" grep -q ' from 127.0.0.1 via 127.0.0.1: ' "$work/cluster-a/btfd-1.log"
check "cluster: stop" server/deploy/cluster.sh stop "$work/cluster-a"

check "cluster: a fresh nginx + 2 btfd (drain run)" up b
check "200 clients, one btfd drained (SIGTERM) mid-way: all complete, none twice, resumed" failover TERM
check "the drained btfd's clients were told 1001 going away" goaway_seen
check "the drained btfd exits by itself" drained_exit
check "cluster: stop" server/deploy/cluster.sh stop "$work/cluster-b"

# a version-4 package (residual levels, lossless WebP textures) through the same failover
lib4=$work/lib4
mkdir -p "$lib4"
check "library: btf compress gen:stone:32 --levels 3 (version 4 over rate-distortion steps)" \
    "$btf" compress gen:stone:32 "$lib4/lap" --components 4 --levels 3 --quiet
check "the version-4 package holds WebP textures" has_webp "$lib4/lap"
check "cluster: a fresh nginx + 2 btfd (version 4)" up c "$lib4"
check "200 clients of a WebP package, one btfd SIGKILLed mid-way: all complete, none twice, resumed" \
    failover KILL lap "$lib4"
check "cluster: stop" server/deploy/cluster.sh stop "$work/cluster-c"

# Raw clients (no retry, no resume: what an operator's own clients are) against a
# btfd that gets SIGTERM 0.2 s after they start connecting: behind an nginx with
# its default proxy_next_upstream (error timeout), and behind a plain HAProxy.
raw_drain() { # raw_drain PORT PID NAME: 400 raw clients connecting over 1 s, SIGTERM to PID 0.2 s in
    local out=$work/raw-$3.txt
    timeout 100 "$clients" "$1" knit "$lib" 400 "$2" 0.2 1000 RAW >"$out" || { cat "$out"; return 1; }
    cat "$out"
}
up_plain() { NGINX_PLAIN_RETRY=1 up "$@" && ! grep -q proxy_next_upstream "$work/cluster-$1/nginx.conf"; }
raw_nginx() { raw_drain "$port" "${pids[0]}" nginx; }
haproxy_up() { # HAProxy (server/deploy/haproxy.cfg.in) in front of cluster e's two btfd
    local d=$work/cluster-e servers="" i=0 p
    for p in "${BTFD_PORTS[@]}"; do servers+="    server b$i 127.0.0.1:$p"$'\n'; i=$((i + 1)); done
    for _ in $(seq 5); do
        hport=$((20000 + RANDOM % 30000))
        awk -v listen="127.0.0.1:$hport" -v servers="$servers" '
            /^#/ { print; next }
            { gsub(/@LISTEN@/, listen) }
            /^@SERVERS@$/ { printf "%s", servers; next }
            { print }' server/deploy/haproxy.cfg.in >"$d/haproxy.cfg"
        haproxy -f "$d/haproxy.cfg" -db >"$d/haproxy.log" 2>&1 &
        hpid=$!
        for _ in $(seq 60); do
            if (exec 3<>"/dev/tcp/127.0.0.1/$hport") 2>/dev/null; then return 0; fi
            kill -0 "$hpid" 2>/dev/null || break
            sleep 0.05
        done
        kill "$hpid" 2>/dev/null; wait "$hpid" 2>/dev/null
    done
    return 1
}
raw_haproxy() { raw_drain "$hport" "${pids[0]}" haproxy; }
drained_exit_of() { # drained_exit_of NAME: cluster NAME's first btfd ends by itself
    for _ in $(seq 150); do kill -0 "${pids[0]}" 2>/dev/null || break; sleep 0.1; done
    ! kill -0 "${pids[0]}" 2>/dev/null && grep -q 'draining: stopped listening' "$work/cluster-$1/btfd-0.log"
}

check "cluster: nginx with its default proxy_next_upstream + 2 btfd" up_plain d
check "400 raw clients through that nginx, one btfd drained 0.2 s in: all complete" raw_nginx
check "the drained btfd exits by itself (nginx)" drained_exit_of d
check "cluster: stop" server/deploy/cluster.sh stop "$work/cluster-d"
if command -v haproxy >/dev/null; then
    check "cluster: 2 btfd" up e
    check "HAProxy (server/deploy/haproxy.cfg.in) in front of them" haproxy_up
    check "400 raw clients through HAProxy, one btfd drained 0.2 s in: all complete" raw_haproxy
    check "the drained btfd exits by itself (HAProxy)" drained_exit_of e
    kill "$hpid" 2>/dev/null; wait "$hpid" 2>/dev/null
    check "cluster: stop" server/deploy/cluster.sh stop "$work/cluster-e"
else
    fail=$((fail + 1))
    echo "deploy: FAIL HAProxy is not installed (make setup installs it)"
fi

# A private library behind nginx's secure_link (server/deploy/nginx-private.conf.in):
# links signed here with Python pass nginx and btfd; a tampered one is refused by
# nginx (403) and an expired one too (410); without nginx, btfd refuses both itself.
secret=$work/secret
printf 'deploy-test secret of 32 bytes!!' >"$secret"
chmod 600 "$secret"
sign_md5() { # sign_md5 NAME EXPIRES: the md5 argument
    python3 -c 'import base64,hashlib,sys
k=open(sys.argv[1],"rb").read()
print(base64.urlsafe_b64encode(hashlib.md5(sys.argv[3].encode()+b"/materials/"+sys.argv[2].encode()+b" "+k).digest()).rstrip(b"=").decode())' "$secret" "$1" "$2"
}
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
private_up() {
    local d=$work/private
    mkdir -p "$d/logs" "$d/tmp"
    "$BTFD" --library "$lib" --port 0 --rescan-ms 0 --token-secret-file "$secret" >"$d/btfd.out" 2>"$d/btfd.log" &
    ppid_btfd=$!
    for _ in $(seq 50); do grep -q listening "$d/btfd.out" 2>/dev/null && break; sleep 0.1; done
    pport=$(sed -n 's/.*127.0.0.1:\([0-9]*\)\/.*/\1/p' "$d/btfd.out")
    nport=$(free_port)
    local user=
    [[ $(id -u) == 0 ]] && user="user $(id -un);"
    sed -e "s|@PREFIX@|$d|g" -e "s|@LISTEN@|127.0.0.1:$nport|" -e "s|@UPSTREAM@|127.0.0.1:$pport|" \
        -e "s|@SECRET@|$(cat "$secret")|" -e "s|@USER@|$user|" server/deploy/nginx-private.conf.in >"$d/nginx.conf"
    nginx -p "$d" -c "$d/nginx.conf" 2>>"$d/logs/error.log" &
    ppid_nginx=$!
    for _ in $(seq 50); do [[ $(get -o /dev/null -w '%{http_code}' "http://127.0.0.1:$nport/materials") == 200 ]] && return 0; sleep 0.1; done
    return 1
}
code_of() { get -o "$work/got" -w '%{http_code}' "$1"; }
private_links() {
    local now exp md5 url bad
    now=$(date +%s)
    exp=$((now + 600))
    md5=$(sign_md5 knit "$exp")
    # a tampered signature: its last character changed (22 base64 characters of 16
    # bytes: the last one is A, Q, g or w, so a fixed replacement could equal it)
    bad=${md5:0:21}A
    [[ $bad == "$md5" ]] && bad=${md5:0:21}Q
    base=$(get "http://127.0.0.1:$nport/materials" | sed -n 's/.*"files":"\([^"]*\)".*/\1/p')
    url="$base$(wt 1)"
    [[ $(code_of "http://127.0.0.1:$nport$url?md5=$md5&expires=$exp") == 200 ]] && cmp "$work/got" "$lib/knit/$(wt 1)" &&
        [[ $(code_of "http://127.0.0.1:$nport$url?md5=$bad&expires=$exp") == 403 ]] &&
        [[ $(code_of "http://127.0.0.1:$nport$url?md5=$md5&expires=$((exp + 1))") == 403 ]] &&
        [[ $(code_of "http://127.0.0.1:$nport$url?md5=$(sign_md5 knit $((now - 5)))&expires=$((now - 5))") == 410 ]] &&
        [[ $(code_of "http://127.0.0.1:$nport$url") == 403 ]] &&
        [[ $(code_of "http://127.0.0.1:$pport$url?md5=$md5&expires=$exp") == 200 ]] &&
        [[ $(code_of "http://127.0.0.1:$pport$url?md5=$bad&expires=$exp") == 403 ]] &&
        [[ $(code_of "http://127.0.0.1:$pport$url") == 403 ]]
}
check "private library: btfd --token-secret-file behind nginx secure_link" private_up
check "signed links pass nginx and btfd; tampered, re-dated, expired, unsigned ones are refused" private_links
kill "${ppid_nginx:-0}" "${ppid_btfd:-0}" 2>/dev/null
wait "${ppid_nginx:-0}" "${ppid_btfd:-0}" 2>/dev/null

echo "deploy: $pass passed, $fail failed"
((fail == 0))
