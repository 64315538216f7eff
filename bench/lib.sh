# bench/lib.sh - shell helpers the bench scripts share (sourced, not run):
#   source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
# package_bytes DIR: the bytes of package DIR as it travels, its chunk files (each once)
# and its manifest (needs jq).
package_bytes() {
    jq -r '[.chunks[].files[]] | unique | .[]' "$1/manifest.json" |
        (cd "$1" && xargs stat -c %s manifest.json) | awk '{ s += $1 } END { print s }'
}
