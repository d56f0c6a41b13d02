# The two commands of the README:
#   make demo   install what is needed, build, run the main job on the sample data
#   make test   install what is needed, build, run every test: the Release
#               build, then the whole suite under AddressSanitizer +
#               UndefinedBehaviorSanitizer, then the threaded tests under
#               ThreadSanitizer
BUILD_DIR ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
# The python3 on some PATHs lacks ROS's modules: CMake is given Debian's.
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3
# The tests a ThreadSanitizer pass runs (CTest label "threads").
TSAN_TARGETS = util_test surf_test index_test bow_test eval_test distributed_test

.PHONY: all deps configure build test test-release test-asan test-tsan demo bench clean

all: build

deps:
	./scripts/install_deps.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD_DIR) -j$(JOBS)

test: test-release test-asan test-tsan

test-release: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j$(JOBS)

test-asan: deps
	cmake --preset asan
	cmake --build build-asan -j$(JOBS)
	cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  ctest --output-on-failure -j$(JOBS) -LE no-sanitizer

test-tsan: deps
	cmake --preset tsan
	cmake --build build-tsan -j$(JOBS) --target $(TSAN_TARGETS)
	cd build-tsan && OPENCV_FOR_THREADS_NUM=1 \
	  TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$(CURDIR)/cmake/tsan.supp \
	  ctest --output-on-failure -j$(JOBS) -L threads

demo: build
	./scripts/demo.sh $(BUILD_DIR)

bench: build
	./scripts/bench.sh $(BUILD_DIR)

clean:
	rm -rf $(BUILD_DIR) build-asan build-tsan out
