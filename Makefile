# Entry points; each installs what is missing first (scripts/setup is idempotent and fast).
.PHONY: setup build run patrol shell test unit integration lint bench soak clean
MINUTES ?= 10

setup:
	@bash scripts/setup

build: setup
	@bash scripts/build

run: build
	scripts/rosenv roslaunch inspection_robot sim.launch

patrol: build
	@bash scripts/patrol

shell: build
	@scripts/rosenv bash

test: build
	@bash scripts/test all

unit: build
	@bash scripts/test unit

integration: build
	@bash scripts/test integration

lint: setup
	@bash scripts/test lint

bench: build
	@bash scripts/bench

soak: build
	@bash scripts/soak $(MINUTES)

clean:
	rm -rf "$$(root=$$PWD; . scripts/ws.sh; echo $$ws)" test_logs
