#!/bin/sh
# The C test program and the C++ host example (tools/examples/cpp-host) under AddressSanitizer +
# UndefinedBehaviorSanitizer with CYCLES create/load/render/free cycles each (default 100), then
# under valgrind's memcheck with VALGRIND_CYCLES of them (default 3: a cycle takes about 45 s
# under valgrind on 2 cores, most of it lavapipe compiling its shaders; 0 skips valgrind). The C
# program renders into memory on lensmap's own device; the C++ host renders into its own VkImage
# on its own device. Run from the repository root after `cargo build --release -p lensmap-capi`:
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

host=tools/examples/cpp-host/host.cpp
# The C++ host's frame: teapot-room, small enough for many cycles.
frame="--em-size 16 --width 64 --height 48 --supersampling 2 --format rgba32f --out $out/host.png"
sanitizers="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"

cc -std=c11 -Wall -Wextra -Werror -g $sanitizers -I engine/capi/include "$here/abi_test.c" \
   -L "$lib" -llensmap_capi -lm -o "$out/abi_test_asan"
c++ -std=c++17 -Wall -Wextra -Werror -ffp-contract=off -g $sanitizers -I engine/capi/include \
   "$host" -L "$lib" -llensmap_capi -lvulkan -o "$out/cpp_host_asan"
asan="$(cc -print-file-name=libasan.so):$lvp"
echo "ASan + UBSan, C program, $cycles cycles:"
LD_PRELOAD="$asan" LD_LIBRARY_PATH="$lib" \
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 "$out/abi_test_asan" "$cycles"
echo "ASan + UBSan, C++ host, $cycles cycles:"
# shellcheck disable=SC2086 # $frame is a list of arguments
LD_PRELOAD="$asan" LD_LIBRARY_PATH="$lib" \
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 "$out/cpp_host_asan" $frame --cycles "$cycles"

[ "$valgrind_cycles" -gt 0 ] || exit 0
cc -std=c11 -Wall -Wextra -Werror -g -I engine/capi/include "$here/abi_test.c" \
   -L "$lib" -llensmap_capi -lm -o "$out/abi_test"
c++ -std=c++17 -Wall -Wextra -Werror -ffp-contract=off -g -O1 -I engine/capi/include "$host" \
   -L "$lib" -llensmap_capi -lvulkan -o "$out/cpp_host"
memcheck="valgrind --leak-check=full --error-exitcode=1 --suppressions=$here/valgrind.supp --quiet"
echo "valgrind memcheck, C program, $valgrind_cycles cycles:"
LD_PRELOAD="$lvp" LD_LIBRARY_PATH="$lib" $memcheck "$out/abi_test" "$valgrind_cycles"
echo "valgrind memcheck, C++ host, $valgrind_cycles cycles:"
# shellcheck disable=SC2086
LD_PRELOAD="$lvp" LD_LIBRARY_PATH="$lib" $memcheck "$out/cpp_host" $frame --cycles "$valgrind_cycles"
