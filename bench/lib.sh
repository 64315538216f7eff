# bench/lib.sh - shell helpers the bench scripts share (sourced, not run):
#   source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
# package_bytes DIR: the bytes of package DIR as it travels, its chunk files (each once)
# and its manifest (needs jq).
package_bytes() {
    jq -r '[.chunks[].files[]] | unique | .[]' "$1/manifest.json" |
        (cd "$1" && xargs stat -c %s manifest.json) | awk '{ s += $1 } END { print s }'
}

# The helpers below run "$BTF", the caller's btf binary.
# whole_lab SRC DIR [EVAL_ARGS...]: btf eval's CIELab of package DIR against SRC, over
# every texel (one decode of the whole package, no per-chunk curve), e.g. --displayed.
whole_lab() { "$BTF" eval "$1" "$2" --json --no-curve "${@:3}" | jq -r .lab_mae; }

# thesis_source SPEC TMP NAME: SPEC as a source btf reads: SOURCE as it is, or
# THESIS_DIR@SIZE (a thesis package at SIZE) as its reconstruction, imported into
# TMP/NAME.btf; prints the source.
thesis_source() {
    if [[ $1 == *@* ]]; then
        "$BTF" import-thesis "${1%@*}" "$2/$3.btf" --size "${1##*@}" >/dev/null
        echo "$2/$3.btf"
    else
        echo "$1"
    fi
}

# thesis_baseline SRC OUT: the thesis format of SRC at k 3, C 8 (btf export-thesis) into
# OUT; prints the bytes of its files.
thesis_baseline() {
    "$BTF" export-thesis "$1" "$2" --k 3 --components 8 >/dev/null
    find "$2" -type f -printf '%s\n' | awk '{ s += $1 } END { print s }'
}
