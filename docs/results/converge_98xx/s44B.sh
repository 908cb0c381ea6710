#!/bin/bash
# lane B, session 44: glint-paper at twice its point's epochs (240, growth), seed 0, curve room 9802
source "$(dirname "$0")/lanes.sh"
$BENCH $GROW --set epochs=240 --methods glint-paper --data /work/data98_9802 --out /work/runs98/e240_grow
