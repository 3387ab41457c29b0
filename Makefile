# Convenience aliases for the scripts in tools/ (the README's commands need no make).
BUILD ?= build
.PHONY: build demo test bench clean
build:
	./tools/build.sh $(BUILD)
demo:
	./tools/demo.sh $(BUILD)
test:
	./tools/test.sh $(BUILD)
bench: build
	./bench/run.sh $(BUILD)
clean:
	rm -rf $(BUILD)
