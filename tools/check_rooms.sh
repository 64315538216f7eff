#!/usr/bin/env bash
# tools/check_rooms.sh [BUILD]: checks that dependencies between the rooms point one
# way (doc/architecture.md). Run after `make build`; `make check` and `make test` do.
#
#   1. includes: every #include "..." (and <...>) of a room's .c/.cpp/.h files is
#      resolved as the compiler would (the file's own folder, then the room folders);
#      a header found only in a room this room may not use is a violation.
#   2. calls between rooms: with nm on BUILD's objects of the product rooms, module A
#      calls module B when A leaves undefined a symbol that B defines (T D B R G S);
#      a call into a room that A's room may not use is a violation.
#   3. call circles: every strongly connected component of that graph with more than
#      one module, listed with one symbol for each call inside it.
#
# A module is one object file of codec/*/, server/, shaders/host/, tools/, bench/gen/,
# bench/eval/ (tests/, fuzz/, bench/*.c and bench/load/ may use anything). Objects
# whose source is gone are left out. Exit: 0 clean, 1 violations (one line each, with
# the detail indented below), 2 the objects are missing.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
build=${build%/}

# ROOM  ALLOWED-INCLUDE-ROOTS: the INC the Makefile (and server/build.mk) gives each
# room; keep in step with its "Rooms" section. "*" means anything. Calls follow the
# same table, except that a room outside codec/ may call any of codec's inner rooms
# (one archive, bounded by what its include path lets it see).
CI=codec/include
rooms="$CI $CI
codec/common $CI codec/common
codec/image $CI codec/common codec/image
codec/format $CI codec/common codec/image codec/format
codec/input $CI codec/common codec/image codec/input
codec/decompress $CI codec/common codec/image codec/format codec/decompress
codec/compress $CI codec/common codec/image codec/format codec/decompress codec/compress
bench/gen $CI codec/common bench/gen
shaders/host $CI codec/common codec/image shaders/host
bench/eval $CI codec/common codec/image codec/format codec/input codec/decompress codec/compress shaders/host bench/eval
tools $CI codec/common codec/image codec/format codec/input codec/decompress codec/compress bench/gen shaders/host bench/eval tools
server $CI codec/common server
tests *
fuzz *
bench *"
codec_rooms='codec/common codec/image codec/format codec/input codec/decompress codec/compress'
product="$CI $codec_rooms server shaders/host tools bench/gen bench/eval"
roots="$CI $codec_rooms bench/gen shaders/host bench/eval tools server tests fuzz"

declare -A allowed
while read -r room inc; do allowed[$room]=$inc; done <<<"$rooms"

# room_of PATH: the room a repository path lies in (longest folder that matches).
room_of() {
    local p=$1 best='' r
    for r in "${!allowed[@]}"; do
        case $p in "$r"/*) [ ${#r} -gt ${#best} ] && best=$r ;; esac
    done
    printf '%s' "$best"
}

violations=0
report() { # report LINE [DETAIL...]
    printf 'check_rooms: %s\n' "$1"
    shift
    local d
    for d in "$@"; do printf '    %s\n' "$d"; done
    violations=$((violations + 1))
}

# --- 1. includes ---
nfiles=0
for room in $product; do
    ok=" ${allowed[$room]} "
    may="${allowed[$room]// //, }/"
    while IFS= read -r file; do
        [ "$(room_of "$file")" = "$room" ] || continue   # bench/gen is not part of bench
        nfiles=$((nfiles + 1))
        dir=${file%/*}
        while IFS=: read -r line text; do
            [[ $text =~ ^[[:space:]]*#[[:space:]]*include[[:space:]]*([\"\<])([^\"\>]+)[\"\>] ]] || continue
            kind=${BASH_REMATCH[1]} hdr=${BASH_REMATCH[2]}
            found=''
            # A quoted include is looked up next to the including file first.
            if [ "$kind" = '"' ] && [ -f "$dir/$hdr" ]; then
                path="$dir/$hdr"
                [[ $hdr != */* ]] || path=$(realpath -m --relative-to=. "$path")
                found=$(room_of "$path")
                [ -n "$found" ] || found=${path%/*}
                if [[ $ok != *" $found "* ]]; then
                    report "$file:$line: wrong-way include \"$hdr\" ($path): $room/ may include only $may"
                fi
                continue
            fi
            hits=''
            for r in $roots; do
                [ -f "$r/$hdr" ] || continue
                [[ $ok == *" $r "* ]] && { hits=''; found=1; break; }
                hits+=" $r/"
            done
            if [ -z "$found" ] && [ -n "$hits" ]; then
                report "$file:$line: wrong-way include \"$hdr\" found only in${hits}: $room/ may include only $may"
            fi
        done < <(grep -n '^[[:space:]]*#[[:space:]]*include' "$file" || true)
    done < <(find "$room" -type f \( -name '*.c' -o -name '*.h' -o -name '*.cpp' \) | sort)
done

# --- 2 and 3. calls between modules ---
objs=()
for room in $product; do
    for o in "$build/$room"/*.o; do
        [ -f "$o" ] || continue
        src=${o#"$build"/}
        src=${src%.o}
        [ -f "$src.c" ] || [ -f "$src.cpp" ] || continue       # stale object
        objs+=("$o")
    done
done
if [ "${#objs[@]}" -eq 0 ] || ! ls "$build"/codec/common/*.o >/dev/null 2>&1; then
    echo "check_rooms: no objects under $build/ (run 'make build' first)" >&2
    exit 2
fi

# Lines "ROOM MODULE D|U SYMBOL" for awk; `main` is each program's own.
symbols() {
    local o mod
    for o in "${objs[@]}"; do
        mod=${o#"$build"/}
        mod=${mod%.o}
        nm -P "$o" | awk -v room="$(room_of "$mod.c")" -v mod="$mod" '
            $1 == "main" { next }
            $2 ~ /^[TDBRGS]$/ { print room, mod, "D", $1 }
            $2 == "U"         { print room, mod, "U", $1 }'
    done
}

out=$(symbols | awk -v rooms="$rooms" '
    BEGIN {
        nr = split(rooms, rl, "\n")
        for (i = 1; i <= nr; i++) {
            n = split(rl[i], f, " ")
            for (j = 2; j <= n; j++) may[f[1], f[j]] = 1
            if (f[2] == "*") any[f[1]] = 1
        }
        # a room outside codec/ that sees its public headers may call the whole library
        # (one archive; its include path bounds what it sees)
        for (i = 1; i <= nr; i++) {
            split(rl[i], f, " ")
            if (f[1] ~ /^codec\// || !((f[1], "codec/include") in may)) continue
            for (j = 1; j <= nr; j++) { split(rl[j], g, " "); if (g[1] ~ /^codec\//) may[f[1], g[1]] = 1 }
        }
    }
    !($2 in idx) { idx[$2] = ++n_mod; name[n_mod] = $2; room_of[$2] = $1 }
    $3 == "D" { def[$4] = def[$4] " " $2; next }
    $3 == "U" { nu++; u_mod[nu] = $2; u_sym[nu] = $4 }
    END {
        # the graph: one symbol per call, the first by name
        for (k = 1; k <= nu; k++) {
            a = u_mod[k]
            if (!(u_sym[k] in def)) continue              # a system library
            nd = split(def[u_sym[k]], ds, " ")
            for (d = 1; d <= nd; d++) {
                b = ds[d]
                if (a == b) continue
                e = idx[a] SUBSEP idx[b]
                if (!(e in via) || u_sym[k] < via[e]) via[e] = u_sym[k]
                reach[e] = 1
            }
        }
        bad = 0; ncall = 0
        for (e in via) {
            ncall++
            split(e, ab, SUBSEP); a = name[ab[1]]; b = name[ab[2]]
            ra = room_of[a]; rb = room_of[b]
            if (!(ra in any) && !((ra, rb) in may)) {
                printf "check_rooms: wrong-way call %s -> %s (%s): %s/ may use only", a, b, via[e], ra
                sep = " "
                for (j = 1; j <= nr; j++) { split(rl[j], f, " "); if ((ra, f[1]) in may) { printf "%s%s/", sep, f[1]; sep = ", " } }
                printf "\n"
                bad++
            }
        }
        # transitive closure (a few dozen modules), then the strongly connected components
        for (k = 1; k <= n_mod; k++)
            for (i = 1; i <= n_mod; i++) {
                if (!((i, k) in reach)) continue
                for (j = 1; j <= n_mod; j++) if ((k, j) in reach) reach[i, j] = 1
            }
        for (i = 1; i <= n_mod; i++) {
            if (i in done) continue
            members = name[i]; m = 1; list[1] = i
            for (j = i + 1; j <= n_mod; j++)
                if (((i, j) in reach) && ((j, i) in reach)) { members = members " " name[j]; list[++m] = j; done[j] = 1 }
            if (m < 2) continue
            printf "check_rooms: call circle of %d modules: %s\n", m, members
            for (x = 1; x <= m; x++)
                for (y = 1; y <= m; y++)
                    if ((list[x], list[y]) in via)
                        printf "    %s -> %s (%s)\n", name[list[x]], name[list[y]], via[list[x], list[y]]
            bad++
        }
        printf "counts %d %d %d\n", n_mod, ncall, bad
    }')
# the last line counts modules, calls and violations; the lines before it are the reports
summary=${out##*$'\n'}
[ "$summary" = "$out" ] || printf '%s\n' "${out%$'\n'*}"
read -r _ nmod ncall bad <<<"$summary"
violations=$((violations + bad))

if [ "$violations" -gt 0 ]; then
    echo "check_rooms: FAILED (see above; the rooms and which may use which: doc/architecture.md)"
    exit 1
fi
echo "check_rooms: OK: the includes of $nfiles files and $ncall calls between $nmod modules, none the wrong way, no call circle"
