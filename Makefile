# The two commands of the README:
#   make demo   install what is needed, build, run the main job on the sample data
#   make test   install what is needed, build once (Release, the build users
#               get), run the whole suite
# and the sanitizer passes CI runs after it:
#   make check  the whole suite under AddressSanitizer (+ UndefinedBehaviorSanitizer on
#               the libraries),
#               then the threaded tests under ThreadSanitizer
BUILD_DIR ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
# The python3 on some PATHs lacks ROS's modules: CMake is given Debian's.
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3
# The tests a ThreadSanitizer pass builds and runs (CTest label "threads").
TSAN_TARGETS = util_test surf_test storage_test retrieval_test query_test builder_test \
  session_test eval_test distributed_test
ASAN_ENV = ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
TSAN_ENV = OPENCV_FOR_THREADS_NUM=1 \
  TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$(CURDIR)/cmake/tsan.supp

.PHONY: all deps configure build test test-release check check-asan check-tsan test-asan \
        test-tsan demo bench readme-options clean

all: build

deps:
	./scripts/install_deps.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD_DIR) -j$(JOBS)

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j$(JOBS)

# The name earlier versions used for the Release pass.
test-release: test

check: check-asan check-tsan

# Sanitizer trees build with -O1 -g1 (presets in CMakePresets.json) and Ninja:
# they exist to run the tests, so only what the tests need is built.
check-asan: deps
	cmake --preset asan
	cmake --build build-asan -j$(JOBS)
	cd build-asan && $(ASAN_ENV) ctest --output-on-failure -j$(JOBS) -LE no-sanitizer

check-tsan: deps
	cmake --preset tsan
	cmake --build build-tsan -j$(JOBS) --target $(TSAN_TARGETS)
	cd build-tsan && $(TSAN_ENV) ctest --output-on-failure -j$(JOBS) -L threads

test-asan: check-asan
test-tsan: check-tsan

demo: build
	./scripts/demo.sh $(BUILD_DIR)

bench: build
	./scripts/bench.sh $(BUILD_DIR)

# The README's option tables from the library's option tables (a test
# fails while they are stale).
readme-options: build
	python3 scripts/option_tables.py $(BUILD_DIR)/src/placedb/exe/placedb README.md

clean:
	rm -rf $(BUILD_DIR) build-asan build-tsan out
