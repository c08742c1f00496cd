#!/bin/sh
# Build ntdda's analysis library (its own CMake build, Release, -O2, no GUI) and our step timer
# against it.
#
#     benchmarks/ntdda_beside/build.sh NTDDA_CHECKOUT [BUILD_DIR]
#
# NTDDA_CHECKOUT: a checkout of github.com/doolin/ntdda (built as it is; nothing in it is changed).
# BUILD_DIR (default /tmp/ntdda-beside-build): where the library and ``step_timer`` go.
# Needs cmake, a C compiler and libxml2's headers (Debian: apt-get install cmake libxml2-dev).
#
# -fcommon: ntdda's headers define globals that several of its files include; compilers since
# GCC 10 put such tentative definitions in separate places by default (-fno-common) and the link
# then fails with "multiple definition". -fcommon restores the old behaviour; no source change.
set -eu
src=$(cd "${1:?usage: build.sh NTDDA_CHECKOUT [BUILD_DIR]}" && pwd)
out=${2:-/tmp/ntdda-beside-build}
here=$(cd "$(dirname "$0")" && pwd)
cc=${CC:-cc}
cmake -S "$src" -B "$out/ntdda" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTS=OFF \
      -DCMAKE_C_FLAGS="-fcommon" -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" >"$out.cmake.log" 2>&1 \
  || { tail -20 "$out.cmake.log"; exit 1; }
cmake --build "$out/ntdda" --target dda -j "${JOBS:-2}" >"$out.build.log" 2>&1 \
  || { tail -20 "$out.build.log"; exit 1; }
xml_cflags=$(pkg-config --cflags libxml-2.0 2>/dev/null || echo -I/usr/include/libxml2)
$cc -O2 -fcommon -I"$src/include" -I"$src/src/platform/stubs" $xml_cflags \
    -o "$out/step_timer" "$here/step_timer.c" "$out/ntdda/src/libdda.a" \
    -Wl,--wrap=display $(pkg-config --libs libxml-2.0 2>/dev/null || echo -lxml2) -lm
# contact_log: the same timer with ntdda's contact judge df22 wrapped (benchmarks/quiet16.py)
$cc -O2 -fcommon -I"$src/include" -I"$src/src/platform/stubs" $xml_cflags \
    -o "$out/contact_log" "$here/step_timer.c" "$here/contact_log.c" "$out/ntdda/src/libdda.a" \
    -Wl,--wrap=display -Wl,--wrap=df22 $(pkg-config --libs libxml-2.0 2>/dev/null || echo -lxml2) -lm
echo "$out/step_timer"
