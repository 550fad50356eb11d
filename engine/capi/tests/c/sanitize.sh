#!/bin/sh
# The C test program under AddressSanitizer + UndefinedBehaviorSanitizer with CYCLES
# create/load/render/free cycles (default 100), then under valgrind's memcheck with
# VALGRIND_CYCLES of them (default 3: a cycle takes 1–2 min under valgrind on 2 cores, most of it
# lavapipe compiling its shaders). Run from the repository root after
# `cargo build --release -p lensmap-capi`:
#     engine/capi/tests/c/sanitize.sh [CYCLES [VALGRIND_CYCLES]]
#
# Lavapipe (libvulkan_lvp.so) is preloaded in both runs. Without it the Vulkan loader dlcloses
# the driver when each instance is destroyed, and what the driver allocated per load is then
# reported as leaked from an "<unknown module>" (about 128 bytes a cycle, measured; none of it in
# lensmap's frames). With the driver kept loaded nothing is reported. valgrind.supp holds the two
# suppressions memcheck needs, each explained there.
set -eu
cycles=${1:-100}
valgrind_cycles=${2:-3}
here=$(dirname "$0")
lib=target/release
lvp=$(ls /usr/lib/*/libvulkan_lvp.so 2>/dev/null | head -n 1)
out=${TMPDIR:-/tmp}/lensmap-sanitize
mkdir -p "$out"

cc -std=c11 -Wall -Wextra -Werror -g -fsanitize=address,undefined -fno-omit-frame-pointer \
   -fno-sanitize-recover=undefined -I engine/capi/include "$here/abi_test.c" \
   -L "$lib" -llensmap_capi -lm -o "$out/abi_test_asan"
echo "ASan + UBSan, $cycles cycles:"
LD_PRELOAD="$(cc -print-file-name=libasan.so):$lvp" LD_LIBRARY_PATH="$lib" \
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 "$out/abi_test_asan" "$cycles"

cc -std=c11 -Wall -Wextra -Werror -g -I engine/capi/include "$here/abi_test.c" \
   -L "$lib" -llensmap_capi -lm -o "$out/abi_test"
echo "valgrind memcheck, $valgrind_cycles cycles:"
LD_PRELOAD="$lvp" LD_LIBRARY_PATH="$lib" valgrind --leak-check=full --error-exitcode=1 \
    --suppressions="$here/valgrind.supp" --quiet "$out/abi_test" "$valgrind_cycles"
