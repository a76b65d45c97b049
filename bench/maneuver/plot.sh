#!/bin/sh
# Plots the CSVs of `bench_maneuver --csv-dir DIR` (first layer, as the paper's Fig. 7-9):
# DIR/maneuver_cross_track.png, DIR/maneuver_along_track.png, DIR/maneuver_speed.png.
# Needs gnuplot (apt-get install gnuplot-nox).
set -e
dir=${1:?usage: plot.sh CSV_DIR}
command -v gnuplot > /dev/null || { echo "plot.sh: gnuplot not found" >&2; exit 1; }
plot_one() {  # column title ylabel output
  gnuplot <<GP
set datafile separator ","
set terminal pngcairo size 1000,1100 font ",10"
set output "$dir/$4"
set multiplot layout 4,1 title "$2, first layer (z < 0.6 mm)"
set grid
set termoption noenhanced
set xlabel "time [s]"
set ylabel "$3"
first(z, v) = (z < 0.0006 ? v : 1/0)
do for [s in "constant every_transition sharp_corner sharp_corner_arc"] {
  set title s
  plot "$dir/maneuver_".s.".csv" using (first(\$4, \$1)):(first(\$4, \$$1)) with lines notitle
}
unset multiplot
GP
}
plot_one 8 "cross-track error e (Eq. 70)" "e [m]" maneuver_cross_track.png
plot_one 7 "along-track error s (Eq. 70)" "s [m]" maneuver_along_track.png
plot_one 10 "extruder speed" "||x_2|| [m/s]" maneuver_speed.png
echo "wrote $dir/maneuver_cross_track.png $dir/maneuver_along_track.png $dir/maneuver_speed.png"
