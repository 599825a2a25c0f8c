# SafeState: every target installs what it needs (Debian packages, only the missing
# ones) and works from a clean clone. Quick start: `make run`, then `make test`.
SHELL := /bin/bash
.DEFAULT_GOAL := build

BUILD_DIR := build
BIN := $(BUILD_DIR)/bin
DEPS := tools/scripts/install-deps.sh

VENV := .venv
# The C# client's enums and alarm table, generated from the core's tables by gen_docs.
CS_NAMES := clients/csharp/SafeState.Client/Generated/Names.g.cs

.PHONY: build test test-asan test-tsan fuzz coverage docs embedded run demo bench bench-check clean deps hmi lint csharp opcua ros2

deps:
	@$(DEPS) build

$(BUILD_DIR)/build.ninja: CMakeLists.txt CMakePresets.json | deps
	cmake --preset default

build: deps $(BUILD_DIR)/build.ninja
	cmake --build --preset default

# Python tools for the protocol tests (pytest, websockets), pinned, in a local venv.
# Real arms' URDFs for test_robot_vs_pinocchio.py (example-robot-data, ~131 MB, pip's cache
# keeps the download): installed into the venv, never copied into the repository.
$(VENV)/.stamp: tests/integration/requirements.txt tests/integration/requirements-robots.txt
	@$(DEPS) python
	python3 -m venv $(VENV)
	$(VENV)/bin/pip install -q -r tests/integration/requirements.txt
	$(VENV)/bin/pip install -q -r tests/integration/requirements-robots.txt
	touch $@

# The operator HMI (TypeScript, Vite, three.js), served by the gateway from hmi/dist.
# Needs Node.js >= 20.19 with npm; `npm ci` runs only when node_modules is missing or the
# lock file changed (stamp).
HMI_SRC := $(shell find hmi/src -type f 2>/dev/null) adapters/opcua/src/backoff.ts hmi/index.html hmi/vite.config.ts hmi/tsconfig.json

hmi/node_modules/.stamp: hmi/package-lock.json hmi/package.json
	@node -e 'const [a,b]=process.versions.node.split(".").map(Number); process.exit(a>20||(a==20&&b>=19)?0:1)' || \
	  { echo "hmi: needs Node.js >= 20.19 with npm (found: $$(node --version 2>/dev/null || echo none))" >&2; exit 1; }
	cd hmi && npm ci --no-audit --no-fund
	touch $@

hmi/dist/index.html: hmi/node_modules/.stamp $(HMI_SRC)
	cd hmi && npm run build

hmi: hmi/dist/index.html

# The C# client library, console and NUnit tests (Debian's Mono 6.8 and NUnit 2.6, no
# NuGet) into clients/csharp/bin/; `make test` runs the tests (CTest csharp_client).
csharp:
	@$(DEPS) csharp
	clients/csharp/build.sh

# The OPC 40010-1 (Robotics) server (TypeScript, node-opcua), started by `safestate run`
# from adapters/opcua/dist. Same Node.js as the HMI; `npm ci` only when the lock changed.
OPCUA_SRC := $(shell find adapters/opcua/src -type f 2>/dev/null) adapters/opcua/tsconfig.json

adapters/opcua/node_modules/.stamp: adapters/opcua/package-lock.json adapters/opcua/package.json
	@node -e 'process.exit(Number(process.versions.node.split(".")[0]) >= 20 ? 0 : 1)' || \
	  { echo "opcua: needs Node.js >= 20 with npm (found: $$(node --version 2>/dev/null || echo none))" >&2; exit 1; }
	cd adapters/opcua && npm ci --no-audit --no-fund
	touch $@

adapters/opcua/dist/main.js: adapters/opcua/node_modules/.stamp $(OPCUA_SRC)
	cd adapters/opcua && npm run build
	touch $@

opcua: adapters/opcua/dist/main.js

# The ROS 2 adapter (docs/ros2.md): ROS 2 Jazzy's rclpy and message packages from PyPI into a
# venv of their own (no ROS installation; every version pinned in adapters/ros2/requirements.txt),
# and its interface package safestate_msgs generated with the registry's rosidl packages.
# `safestate run --ros2` (`make run ROS2=1`) starts it from there.
ROS2_VENV := .venv-ros2
$(ROS2_VENV)/.stamp: adapters/ros2/requirements.txt adapters/ros2/install.sh $(wildcard adapters/ros2/safestate_msgs/msg/*.msg) adapters/ros2/safestate_msgs/CMakeLists.txt
	@$(DEPS) ros2
	adapters/ros2/install.sh $(ROS2_VENV) build-ros2
	touch $@

ros2: $(ROS2_VENV)/.stamp

test: build $(VENV)/.stamp hmi/dist/index.html csharp adapters/opcua/dist/main.js $(ROS2_VENV)/.stamp
	@$(DEPS) embedded browser ecat
	ctest --preset default

# AddressSanitizer + UndefinedBehaviorSanitizer over the whole suite, built with clang-19
# (the fuzz group): gcc 12 took 15 minutes of CI's 2 cores for this tree, clang 19 about 7.
test-asan: deps $(VENV)/.stamp hmi/dist/index.html
	@$(DEPS) embedded browser fuzz
	cmake --preset asan
	cmake --build --preset asan
	ctest --preset asan

# libFuzzer (clang-19, ASan + UBSan): each target for FUZZ_SECONDS, starting from the
# seed corpus in tests/fuzz/corpus; new inputs go to build-fuzz/corpus, findings to
# build-fuzz/findings (and fail the target). The engines are built in the asan tree
# (compiled with -fsanitize=fuzzer-no-link): after `make test-asan` nothing is rebuilt.
FUZZ_SECONDS ?= 60
FUZZ_TARGETS := core scenario protocol safety esi
fuzz: deps
	@$(DEPS) fuzz
	cmake --preset asan
	cmake --build --preset asan --target $(foreach t,$(FUZZ_TARGETS),fuzz_$(t)_libfuzzer)
	@mkdir -p build-fuzz/findings
	@for t in $(FUZZ_TARGETS); do \
	  mkdir -p build-fuzz/corpus/$$t; \
	  echo "fuzz_$$t: $(FUZZ_SECONDS) s"; \
	  build-asan/bin/fuzz_$${t}_libfuzzer -max_total_time=$(FUZZ_SECONDS) -max_len=4096 -timeout=10 -print_final_stats=1 \
	    -artifact_prefix=build-fuzz/findings/$$t- build-fuzz/corpus/$$t tests/fuzz/corpus/$$t 2>&1 | \
	    grep -E "^(#[0-9]+ *DONE|stat::number_of_executed_units|stat::new_units_added|==|SUMMARY|fuzz_)" || exit 1; \
	done

# clang-19 source-based coverage with MC/DC of core/ and motion/ (build-cov/coverage.txt).
coverage: deps
	@$(DEPS) fuzz
	tools/scripts/coverage.sh

# ThreadSanitizer over the bridge, rings and runtime threads.
test-tsan: deps
	@$(DEPS) fuzz
	cmake --preset tsan
	cmake --build --preset tsan --target test_bridge
	ctest --preset tsan -R '^(Ring|SeqLock|Segment|RuntimeBridge)'


# Regenerate the documentation that mirrors the code (transition table, alarm list,
# state diagram). CI fails (test docs_up_to_date) when the committed copy is stale.
# clang-tidy and cppcheck on core/ and motion/ (configuration: .clang-tidy, tools/scripts/lint.sh).
lint: build
	@$(DEPS) lint
	tools/scripts/lint.sh $(BUILD_DIR)

docs: build adapters/opcua/dist/main.js
	$(BIN)/gen_docs --out docs --csharp $(CS_NAMES)
	node adapters/opcua/dist/main.js --write-node-map docs/opcua-nodes.md > /dev/null
	python3 tools/trace/traceability.py

embedded:
	@$(DEPS) embedded
	tools/scripts/embedded.sh

# The live cell: core in a real-time loop on the simulated cell, gateway with the HMI,
# OPC UA at opc.tcp://127.0.0.1:4840 (read-only without --opcua-users-file; docs/opcua.md).
# SAFETY=FILE: run with that safety configuration (SPEC §10; `make run SAFETY=examples/safety/cell.json`);
# without it, the built-in one.
SAFETY ?=
SAFETY_ARG = $(if $(SAFETY),--safety $(SAFETY))
# ROS2=1: with the ROS 2 adapter (node /safestate, DDS on this host only; docs/ros2.md), on
# ROS_DOMAIN_ID's domain (else 0).
ROS2 ?=
ROS2_ARG = $(if $(filter-out 0,$(ROS2)),--ros2)
# `make run ROBOT=path/to/arm.urdf` (issue 38; optional ROBOT_BASE, ROBOT_FLANGE): another arm
# than the built-in ABB IRB 120 (docs/robot.md "Bring your own arm").
ROBOT_ARG = $(if $(ROBOT),--robot $(ROBOT)) $(if $(ROBOT_BASE),--base $(ROBOT_BASE)) $(if $(ROBOT_FLANGE),--flange $(ROBOT_FLANGE))
# SPEC §14's cross-check window. `make run` is the quick start on a development host, whose
# scheduler keeps a channel process from running a few milliseconds now and then (on a 2-CPU VM
# a browser opening the HMI did, 2.9-3.5 ms: docs/two-channels.md "On a shared host"): without a
# safety configuration it runs a 15-cycle window, which `safestate run` logs; a cell's window
# is its safety configuration's (`channels.cross_check_cycles`, SPEC's default 2), and
# `safestate run` alone keeps SPEC's 2. CROSS_CHECK_CYCLES=N sets another (2: SPEC's).
ifeq ($(origin CROSS_CHECK_CYCLES),undefined)
CROSS_CHECK_CYCLES := $(if $(SAFETY),,15)
endif
CROSS_CHECK_ARG = $(if $(CROSS_CHECK_CYCLES),--cross-check-cycles $(CROSS_CHECK_CYCLES))
run: build hmi/dist/index.html adapters/opcua/dist/main.js $(if $(filter-out 0,$(ROS2)),$(ROS2_VENV)/.stamp)
	$(BIN)/safestate run --bind 127.0.0.1 --port 8080 --db safestate-events.db --static hmi/dist $(SAFETY_ARG) $(ROS2_ARG) $(ROBOT_ARG) $(CROSS_CHECK_ARG)

# Measurements (not tests), all of issue 7 in one run; rewrites docs/performance.md.
# RT_SECONDS=10 make bench for a quick look (the document then says 10 s).
bench: $(VENV)/.stamp adapters/opcua/dist/main.js
	@$(DEPS) build bench embedded ecat
	cmake --preset default
	cmake --build --preset default
	cmake --build --preset default --target ws_rtt
	VENV_PY=$(VENV)/bin/python python3 bench/run.py

# The exhaustive checker at depth 5 (CHECK_DEPTH=N for another): minutes and gigabytes, so
# not in `make test` (depth 3) nor `safestate check`'s default (4); docs/verification.md
# reports the figures.
bench-check: deps $(BUILD_DIR)/build.ninja
	cmake --build --preset default --target safestate
	bench/check_deep.sh

# The narrated replay of examples/demo.scn (no server).
demo: build
	$(BIN)/safestate demo examples/demo.scn

clean:
	rm -rf $(BUILD_DIR) build-debug build-m4 build-tsan build-asan build-fuzz build-cov build-cargo build-ros2 build-ros2.configure.log $(VENV) $(ROS2_VENV) hmi/dist hmi/node_modules clients/csharp/bin adapters/opcua/dist adapters/opcua/node_modules

# The cell over real EtherCAT frames: `safestate ecat-sim` (EMULATED subdevices) in a
# network namespace of its own on one end of a veth pair; `safestate run --fieldbus
# ethercat` in this namespace on the other end, so the HMI stays on 127.0.0.1:8080
# (ECAT_PORT). Needs root (namespaces, raw sockets). The namespace and the pair go away on
# Ctrl-C. The HMI's simulated-cell panel drives the emulator through its control socket.
ECAT_NS ?= safestate-ecat
ECAT_CONTROL ?= /tmp/safestate-ecat-sim.sock
ECAT_PORT ?= 8080
# The real-time loop and the emulated segment on one CPU (docs/ethercat.md, "Timing on a shared host").
ECAT_CPU ?= $(shell echo $$(( $$(nproc) - 1 )))
# BUS=FILE: the master uses that bus configuration (e.g. one made by `safestate ecat-config`
# from ESI files, docs/ethercat.md "ESI"); without it, the built-in one.
BUS ?=
BUS_ARG = $(if $(BUS),--bus-config $(BUS))
# SPEC §14's two channels in processes of their own over the segment by default (K1 from A,
# K2 from B, both contacts and the drives' 0x60E4 on the wire; docs/two-channels.md);
# CHANNELS=1: one channel.
CHANNELS ?=
CHANNELS_ARG = $(if $(CHANNELS),--channels $(CHANNELS))
.PHONY: run-ethercat
run-ethercat: build hmi/dist/index.html adapters/opcua/dist/main.js
	@[ "$$(id -u)" = 0 ] || { echo "run-ethercat: needs root (a network namespace, a veth pair and raw sockets): sudo make run-ethercat" >&2; exit 1; }
	@$(DEPS) ecat
	@ip netns del $(ECAT_NS) 2>/dev/null || true
	ip netns add $(ECAT_NS)
	ip link add ss-ecm type veth peer name ss-ecs netns $(ECAT_NS)
	ip link set ss-ecm up
	ip -n $(ECAT_NS) link set ss-ecs up
	@trap 'kill $$SIM 2>/dev/null; wait $$SIM 2>/dev/null; ip link del ss-ecm 2>/dev/null; ip netns del $(ECAT_NS) 2>/dev/null; echo "run-ethercat: namespace $(ECAT_NS) and veth pair removed"' EXIT; \
	  trap 'exit 130' INT TERM; \
	  rm -f $(ECAT_CONTROL); \
	  ip netns exec $(ECAT_NS) $(BIN)/safestate ecat-sim --ifname ss-ecs --control $(ECAT_CONTROL) --cpu $(ECAT_CPU) & SIM=$$!; \
	  for i in $$(seq 100); do [ -S $(ECAT_CONTROL) ] && break; kill -0 $$SIM 2>/dev/null || exit 1; sleep 0.05; done; \
	  [ -S $(ECAT_CONTROL) ] || { echo "run-ethercat: ecat-sim did not open $(ECAT_CONTROL)" >&2; exit 1; }; \
	  $(BIN)/safestate run --fieldbus ethercat --ifname ss-ecm --cpu $(ECAT_CPU) --ecat-sim-control $(ECAT_CONTROL) --bind 127.0.0.1 \
	    --port $(ECAT_PORT) --db safestate-events.db --static hmi/dist $(SAFETY_ARG) $(BUS_ARG) $(ROBOT_ARG) $(CHANNELS_ARG) $(CROSS_CHECK_ARG)
