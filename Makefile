# Convenience entry points; the build itself is CMake (see CMakeLists.txt).
BUILD ?= build
JOBS ?= $(shell nproc)

.PHONY: deps build demo test bench clean

deps:
	./tools/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release
	cmake --build $(BUILD) -j $(JOBS)

# The main job on bundled real data.
demo: build
	./tools/demo.sh $(BUILD)

test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

bench: build
	./bench/run.sh $(BUILD)

clean:
	rm -rf $(BUILD)
