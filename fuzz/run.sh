#!/usr/bin/env bash
# Builds the libFuzzer targets with clang in a separate build directory and runs each for a
# bounded time (issue 4). Usage: fuzz/run.sh [seconds per target]   (default 30)
# Environment: BUILD_DIR (default build-fuzz), JOBS (default 2), TARGETS (default "protocol cao http"),
#              CXX (default clang++).
# The seed corpora and the protocol dictionary are written into the build directory; findings go
# to $BUILD_DIR/artifacts/<target>/. Exit status: 0 when no target found a crash.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_PER_TARGET="${1:-${FUZZ_TIME:-30}}"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-fuzz}"
JOBS="${JOBS:-2}"
TARGETS="${TARGETS:-protocol cao http}"
CXX="${CXX:-clang++}"
SAN="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined"

if ! command -v "$CXX" >/dev/null; then
  echo "fuzz/run.sh: $CXX not found (Debian: apt-get install clang libclang-rt-14-dev)" >&2
  exit 2
fi

# --- configure and build -------------------------------------------------------------------
SRC="$ROOT"
if ! grep -q V4R_FUZZ "$ROOT/CMakeLists.txt"; then
  # The top-level CMakeLists.txt does not add fuzz/ yet: wrap the tree in a small project that does.
  SRC="$BUILD_DIR/wrapper"
  mkdir -p "$SRC"
  cat >"$SRC/CMakeLists.txt" <<WRAP
cmake_minimum_required(VERSION 3.22)
project(v4r_fuzz_wrapper LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 20)
add_subdirectory("$ROOT" v4r)
add_subdirectory("$ROOT/fuzz" fuzz)
WRAP
fi
cmake --no-warn-unused-cli -S "$SRC" -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_COMPILER="$CXX" -DCMAKE_CXX_FLAGS="$SAN" \
  -DV4R_FUZZ=ON -DV4R_BUILD_TESTS=OFF -DV4R_BUILD_BENCH=OFF >/dev/null
build_targets=()
for t in $TARGETS; do build_targets+=("v4r_${t}_fuzz"); done
cmake --build "$BUILD_DIR" -j "$JOBS" --target "${build_targets[@]}"

# --- seed corpora (text, generated here so that no binary file is committed) ------------------
seed() {  # seed <dir> <name> <content>
  mkdir -p "$1"
  printf '%s' "$3" >"$1/seed-$2"
}
P="$BUILD_DIR/corpus/protocol"
seed "$P" hello 'Hello version=1 auth=required
OK GetParam name=track.rows value=24 doc="rows per window"
ERR AddObject code=exists msg="object \"box\" exists"
'
seed "$P" objects 'AddObject name=box
AddModel object=box format=cao bytes=40
V1
# cube
1
0 0 0
0
0
0
0
Ping
AddModel object=box path="/data/my models/box.cao" format=cao
RemoveObject name=box
'
seed "$P" features 'AddObject name=cup
AddFeature object=cup type=junction id=J1 p=0.1,-0.2,3e-1
AddFeature object=cup type=junction id=J2 p=+1,.5,5.
AddFeature object=cup type=line id=L1 from=J1 to=J2
AddFeature object=cup type=circle id=C1 center=0,0,0.1 normal=0,0,1 radius=0.04
RemoveFeature object=cup id=L1
SetPose object=cup t=0.01,-0.02,0.5 r=0,3.14159265358979,0
'
seed "$P" control 'Subscribe what=ObjectPose rate=30
Subscribe what=SystemStatus
Unsubscribe what=SystemStatus
SetParam name=track.rows value="32"
GetParam name=track.rows
ListParams
Start
Pause
Display on
Log on file=/tmp/cycle.csv
Log off
Auth token="a \\ b"
Quit
'
seed "$P" events 'ObjectPose object=box frame=17 stamp=0.5666666666666667 t=0.01,-0.02,0.5 q=1,0,0,0 cov=1e-06,0,0,0,0,0,0,1e-06,0,0,0,0,0,0,1e-06,0,0,0,0,0,0,1e-04,0,0,0,0,0,0,1e-04,0,0,0,0,0,0,1e-04 quality=0.93 status=tracking
SystemStatus frame=41 cycle_ms=12.375 features_found=120 features_used=97 outliers=11 overruns=3
SystemStatus frame=42 cycle_ms=1.5 features_found=0 features_used=0 outliers=0 overruns=3 failed=1
'
seed "$P" errors 'AddObject name="unterminated
AddFeature object=box type=junction id=J1 p=nan,1e999,0x10
addobject name=box

Display maybe
'
seed "$P" overlong "AddObject name=$(head -c 5000 /dev/zero | tr '\0' x)
Ping
AddModel object=box format=cao bytes=5
V1
0Ping
"
C="$BUILD_DIR/corpus/cao"
seed "$C" cube 'V1
# a unit cube: 8 points, 12 lines, 6 faces from lines
8
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
12
0 1
1 2
2 3
3 0
4 5
5 6
6 7
7 4
0 4
1 5
2 6
3 7
6
4 0 1 2 3
4 4 5 6 7
4 0 9 4 8
4 1 10 5 9
4 2 11 6 10
4 3 8 7 11
0
0
0
'
seed "$C" points_faces 'V1
4
0 0 0
0.1 0 0
0.1 0.1 0
0 0.1 0
0
0
1
4 0 1 2 3
1
0 1 0.05
1
0 1 2 0.05
'
seed "$C" load 'V1
load("part.cao", t=[0.1, 0, 0], tu=[0, 0, 1.57])
0
0
0
0
'

H="$BUILD_DIR/corpus/http"
seed "$H" get $'GET / HTTP/1.0\r\nHost: x\r\n\r\n'
seed "$H" status $'GET /status.json?token=s3cret&x=1 HTTP/1.1\r\nHost: localhost:8080\r\nAccept: */*\r\n\r\n'
seed "$H" stream $'HEAD /stream.mjpg?token= HTTP/1.1\r\nUser-Agent: Mozilla/5.0 (X11)\r\nConnection: keep-alive\r\n\r\nbody'
seed "$H" bad $'POST /x HTTP/2\r\n: no name\r\n\r\n'
seed "$H" lf $'GET /index.html HTTP/1.0\n\n'

# libFuzzer dictionary for the protocol: the words of docs/protocol.md.
DICT="$BUILD_DIR/protocol.dict"
: >"$DICT"
for w in Hello OK ERR AddObject RemoveObject AddModel AddFeature RemoveFeature SetPose Subscribe \
         Unsubscribe SetParam GetParam ListParams Start Pause Display Log Ping Quit Auth ObjectPose \
         SystemStatus name= object= format= bytes= path= type= id= p= from= to= center= normal= \
         radius= t= r= what= rate= value= file= token= frame= stamp= q= cov= quality= status= \
         cycle_ms= features_found= features_used= outliers= overruns= failed= code= msg= version= auth= \
         junction line circle cao obj ply stl on off tracking degraded lost failed forbidden required nan inf e-324 \
         e308 '\"' '\\' '\x0d\x0a' '\x00' '\xff'; do
  printf '"%s"\n' "$w" >>"$DICT"
done

# --- run ---------------------------------------------------------------------------------------
status=0
for t in $TARGETS; do
  bin="$BUILD_DIR/bin/v4r_${t}_fuzz"
  art="$BUILD_DIR/artifacts/$t"
  mkdir -p "$art" "$BUILD_DIR/corpus/$t"
  extra=()
  [ "$t" = protocol ] && extra+=("-dict=$DICT" -max_len=12000)
  [ "$t" = cao ] && extra+=(-max_len=8192 -timeout=10)
  [ "$t" = http ] && extra+=(-max_len=9000)
  echo "== $t: fuzzing for ${SECONDS_PER_TARGET}s"
  log="$BUILD_DIR/fuzz-$t.log"
  if "$bin" "$BUILD_DIR/corpus/$t" -max_total_time="$SECONDS_PER_TARGET" -print_final_stats=1 \
       -artifact_prefix="$art/" -rss_limit_mb=2048 "${extra[@]}" >"$log" 2>&1; then
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)
    echo "   ok: ${execs:-?} executions, corpus $(ls "$BUILD_DIR/corpus/$t" | wc -l) inputs"
  else
    status=1
    echo "   FAILED: see $log; inputs in $art/:"
    grep -E 'ERROR|SUMMARY|property violated' "$log" | head -5 || true
    for f in "$art"/*; do [ -f "$f" ] && echo "   $f: $(xxd -p "$f" | tr -d '\n' | head -c 400)"; done
  fi
done
exit $status
