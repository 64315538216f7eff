#!/usr/bin/env bash
# make demo: prepares a sample library (generated materials, plus the thesis
# materials when $BTF_SHARED/data holds them, see README.md), starts btfd and prints the URL.
# Env: BUILD (build dir), LIBRARY (default library/), PORT (default 8080), BIND.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
LIBRARY=${LIBRARY:-library}
PORT=${PORT:-8080}
BIND=${BIND:-127.0.0.1}
SHARED=${BTF_SHARED:-../shared}
BTF="$BUILD/btf"
mkdir -p "$LIBRARY"

# add NAME SOURCE [compress options...]: compresses SOURCE into the library once.
add() {
    local name=$1 src=$2
    shift 2
    if [ -f "$LIBRARY/$name/manifest.json" ]; then
        echo "demo: $LIBRARY/$name already built"
        return
    fi
    echo "demo: compressing $src -> $LIBRARY/$name"
    "$BTF" compress "$src" "$LIBRARY/$name" --quiet "$@"
    if "$BTF" --help 2>/dev/null | grep -q '^  render '; then
        "$BTF" render "$LIBRARY/$name" "$LIBRARY/$name/thumbnail.png" --size 128 >/dev/null 2>&1 ||
            echo "demo: no thumbnail for $name"
    fi
}

add knit gen:knit:128 --k 3 --components 8 --levels 4
add tiles gen:tiles:128 --k 3 --components 8 --levels 4
add stone gen:stone:128 --k 3 --components 8 --levels 4
for m in wool corduroy; do
    if [ -f "$SHARED/data/thesis-ubo2003/$m/meta.json" ]; then
        add "$m" "$SHARED/data/thesis-ubo2003/$m" --k 3 --components 8 --levels 4
    fi
done

# the product page's model (client/pages/product.html): a stool of three glTF materials
# beside the pages at the client root (make build rewrites $BUILD/client, so every run)
"$BTF" gen-model "$BUILD/client/stool.glb"

echo
echo "demo: library $(ls "$LIBRARY" | wc -l) materials in $LIBRARY/"
echo "demo: gallery  http://$BIND:$PORT/"
echo "demo: embed    http://$BIND:$PORT/embed.html"
echo "demo: product  http://$BIND:$PORT/product.html (a glTF stool, two materials)"
echo "demo: stop with Ctrl-C"
# the client as one file (make build: $BUILD/client, tools/bundle.mjs), shaders inside
exec "$BUILD/btfd" --library "$LIBRARY" --port "$PORT" --bind "$BIND" --client "$BUILD/client"
