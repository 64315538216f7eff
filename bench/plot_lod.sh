#!/usr/bin/env bash
# bench/plot_lod.sh - draws doc/figures/budgets.png (bytes each scene streams with
# footprint budgets against sending every package in full) from
# bench/results/lod.txt, written by bench_lod. Run by `make bench`.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
in=bench/results/lod.txt
out=${1:-doc/figures/budgets.png}
[[ -f $in ]] || { echo "plot_lod: $in missing: run make bench first" >&2; exit 1; }
val() { awk -v k="$1" '$1 == k { print $2 }' "$in"; }
data=$(mktemp)
trap 'rm -f "$data" "$out.tmp.png"' EXIT
for s in closeup phone thumbnail grid12; do
    b=$(val "${s}_bytes"); all=$(val "${s}_bytes_everything")
    [[ -n $b && -n $all ]] || { echo "plot_lod: $in lacks $s" >&2; exit 1; }
    echo "$s $(awk -v x="$b" 'BEGIN { print x / 1024 }') $(awk -v x="$all" 'BEGIN { print x / 1024 }')" >>"$data"
done
gnuplot <<GP
set terminal pngcairo size 720,360 font ",10"
set output "$out.tmp.png"
set title "bytes streamed per scene: footprint budget vs every package in full (first frame $(val first_frame_bytes) B)"
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.8 border -1
set ylabel "KiB"
set logscale y
set yrange [10:*]
set grid ytics
set key top right
plot "$data" using 2:xtic(1) title "budget (what the view resolves)", "" using 3 title "send everything"
GP
mv "$out.tmp.png" "$out"
echo "plot_lod: wrote $out"
