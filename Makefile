# v4r: `make demo` and `make test` do all set-up on a fresh Debian machine.
BUILD ?= build
JOBS ?= $(shell nproc)
DEB_PACKAGES := build-essential cmake ninja-build pkg-config libeigen3-dev libopencv-dev libasio-dev \
	libcli11-dev libspdlog-dev libfmt-dev libyaml-cpp-dev libgtest-dev libgmock-dev libbenchmark-dev libassimp-dev \
	libapriltag-dev
# Only for `make test`: headless Chromium checks the monitoring page of `v4r serve`; ViSP's images
# (real cube sequence, .cao models) for tests/visp_cube_test.cpp; python3 runs the README commands
# and the protocol units test; GStreamer's base and good plugins (videotestsrc, multifilesrc, pngdec)
# for the live-camera tests.
# ROS 1 (issue 12): the node's libraries, and rosmaster, rosbag, rostopic and rospy for its test;
# ROS 2 on the wire: Cyclone DDS (serve --ros2) and Fast DDS (the independent reader of its test).
TEST_PACKAGES := chromium visp-images-data python3 gstreamer1.0-plugins-base gstreamer1.0-plugins-good \
	libroscpp-dev libsensor-msgs-dev libgeometry-msgs-dev libstd-msgs-dev libtf2-ros-dev \
	python3-rosmaster python3-rosbag python3-rostopic python3-rospy python3-sensor-msgs python3-geometry-msgs \
	python3-std-msgs python3-opencv \
	cyclonedds-dev cyclonedds-tools libfastrtps-dev
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: all deps test-deps configure build test demo bench fuzz clean
FUZZ_TIME ?= 30

all: build

# Installs only the Debian packages that are missing.
define install_missing
	@missing=""; for p in $(1); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "Installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi
endef

deps:
	$(call install_missing,$(DEB_PACKAGES))

test-deps:
	$(call install_missing,$(TEST_PACKAGES))

$(BUILD)/build.ninja:
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release

configure: deps $(BUILD)/build.ninja

build: configure
	cmake --build $(BUILD) -j $(JOBS)

# The test packages come first and CMake runs again, so that the optional parts they enable (the
# ROS 1 node) are built and tested.
test: deps test-deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release
	cmake --build $(BUILD) -j $(JOBS)
	cd $(BUILD) && V4R_REQUIRE_CHROMIUM=1 V4R_REQUIRE_VISP_IMAGES=1 V4R_REQUIRE_GSTREAMER=1 V4R_REQUIRE_ROS1=1 ctest --output-on-failure -j $(JOBS) --timeout 600

demo: build
	$(BUILD)/bin/v4r demo --out $(BUILD)/demo

bench: build
	$(BUILD)/bin/v4r_bench

# Coverage-guided fuzzing of the protocol parser and the .cao reader (clang + libFuzzer), bounded in time.
fuzz: deps
	@command -v clang++ >/dev/null || $(SUDO) apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev
	fuzz/run.sh $(FUZZ_TIME)

clean:
	rm -rf $(BUILD)
