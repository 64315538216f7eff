#!/usr/bin/env bash
# bench/gpu/build.sh - `make bench-gpu`: a self-contained folder that runs the shader
# bench (bench/bench_shader.c) on a bare Linux machine with only a GPU driver (its
# libEGL and GLES): the bench binary built without OpenImageIO and OSMesa (packages
# read through libpng and libwebp: bench/gpu/btf_image_lite.c), the few shared
# libraries it needs, the shader files and the two packages it draws, made here.
#
#   make bench-gpu                 # writes build/bench-gpu/ (OUT=... elsewhere)
#   build/bench-gpu/run.sh         # there: prints the results, writes results.txt
#
# The folder holds no libEGL, libGLES or libGLdispatch: those come from the GPU's
# driver on the machine that runs it (the bench's EGL host finds the GPU through
# EGL_EXT_platform_device; `platform` in the results says which it used).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
BUILD=${BUILD:-build}
OUT=${OUT:-$BUILD/bench-gpu}
obj=$BUILD/bench-gpu-obj
[[ -x $BUILD/bench/bench_shader ]] || { echo "bench-gpu: $BUILD/bench/bench_shader is missing (make bench builds it)" >&2; exit 1; }
rm -rf "$OUT" "$obj"
mkdir -p "$OUT/lib" "$obj"

src=(codec/common/*.c codec/format/*.c codec/decompress/*.c codec/image/btf_png.c codec/image/btf_webp.c
     shaders/host/btf_gl.c shaders/host/btf_gl_egl.c shaders/host/btf_gl_dirs.c shaders/host/btf_gl_package.c shaders/host/btf_gl_fixed.c
     shaders/host/btf_render.c shaders/host/btf_shader.c shaders/host/btf_env.c
     bench/gpu/btf_image_lite.c bench/gpu/btf_gl_no_osmesa.c bench/gpu/no_lapack.c bench/bench_shader.c)
inc=(-Icodec/include -Icodec/common -Icodec/image -Icodec/format -Icodec/decompress -Icodec/compress
     -Icodec/input -Ishaders/host -Ibench -Ibench/gen -I/usr/include/cjson)
flags=(-std=c11 -O2 -g -fopenmp -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L -DBENCH_READ_ONLY -Wall -Wextra -Werror)
objs=()
for s in "${src[@]}"; do
    o=$obj/$(echo "${s%.c}" | tr / _).o
    cc "${flags[@]}" "${inc[@]}" -c "$s" -o "$o"
    objs+=("$o")
done
# an archive: only the objects the bench reaches are linked (not the writers'
# solvers, which would bring LAPACK); -rpath $ORIGIN/lib: the folder's libraries
# first, wherever it is copied
ar rcs "$obj/libbench.a" "${objs[@]}"
cc -fopenmp -o "$OUT/bench_shader" "$obj/bench_bench_shader.o" "$obj/libbench.a" -Wl,-rpath,'$ORIGIN/lib' \
    -lEGL -lpng16 -lwebp -lz -lcjson -lqhull_r -lm

# the libraries it needs, less the driver's (EGL, GLES, glvnd) and the C library's
ldd "$OUT/bench_shader" | awk '$3 ~ /^\// {print $3}' | while read -r lib; do
    case $(basename "$lib") in
    libEGL* | libGL* | libc.so* | libm.so* | libpthread* | libdl.so* | librt.so* | ld-linux*) ;;
    *) cp -L "$lib" "$OUT/lib/" ;;
    esac
done
mkdir -p "$OUT/shaders"
cp shaders/*.glsl shaders/*.vert shaders/*.frag shaders/manifest.json "$OUT/shaders/"
cp -r shaders/bench "$OUT/shaders/bench"
mkdir -p "$OUT/packages"
"$BUILD/bench/bench_shader" --write-packages "$OUT/packages" >/dev/null
cat >"$OUT/run.sh" <<'RUN'
#!/usr/bin/env bash
# Runs the shader bench of this folder; results on stdout and in results.txt.
# BTF_EGL_PLATFORM=device skips a Mesa display when the machine has one.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export BTF_ROOT=$here BTF_SHADERS=$here/shaders BENCH_PACKAGES=$here/packages
"$here/bench_shader" | tee "$here/results.txt"
RUN
chmod +x "$OUT/run.sh"
du -sh "$OUT"
ls "$OUT/lib"
