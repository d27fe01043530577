# Top-level build and the README's two commands.
#
#   make demo   set up everything (Debian packages, .venv, C build) and run the demo
#   make test   set up everything and run the whole test suite (real vcan; VM if needed)
#   make format apply the code style (ruff format, clang-format; checked by tests/host/test_style.py)
#
# `make all` only builds the C code (C11, -Wall -Wextra -Werror), into build/ (BUILD=DIR: elsewhere).
# `make LAW=DIR` (and `make LAW=DIR mcu`) builds the drive with a user's current law, a folder of C files
# (and headers) and law.eds, into build/laws/<law name>-<8 hex of DIR's path>/, the folder `bench run --law DIR`
# uses: make hands the build to bench/law.py (atomic: a failing build leaves the last good one; it calls this
# Makefile again with BUILD= its work folder). docs/ARCHITECTURE.md, "A law from your own folder".

CC      ?= gcc
LAW     ?=
PYTHON  ?= $(if $(wildcard .venv/bin/python),.venv/bin/python,python3)

ifneq ($(strip $(LAW)),)
ifneq ($(origin BUILD),command line)
LAW_HANDED := 1
endif
endif
ifdef LAW_HANDED
LAW_OTHER := $(filter-out law mcu,$(MAKECMDGOALS))
ifneq ($(LAW_OTHER),)
$(error LAW=$(LAW) $(firstword $(LAW_OTHER)): with LAW, make builds a law's goals, law (the default) and mcu; the \
repository's own goals run without LAW (is it exported in your shell?); a law's builds are build/laws/<name>-*/)
endif
.PHONY: law mcu
law:
	@$(PYTHON) -m bench.law '$(LAW)' $(MAKECMDGOALS)
mcu: $(if $(filter law,$(MAKECMDGOALS)),,law)
else
# -flto: the in-process loop (libhil.so) crosses many small functions of the CANopen slave, the bus and the apps
# per period; link-time inlining makes it ~25% faster (docs/BENCHMARKS.md). -fno-semantic-interposition: calls
# inside the library need not go through the PLT. -std=c11 keeps -ffp-contract=off: the arithmetic is the same.
OPT     ?= -O2 -g -flto=auto -fno-semantic-interposition
# -ffile-prefix-map=<source folder>=. for a build that keeps no path of its machine (setup.py: a package).
PATHMAP ?=
WARN    := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wdouble-promotion
CSTD    := -std=c11
# Portable cores: no OS headers, float32-clean in the firmware.
CFLAGS_CORE := $(CSTD) $(OPT) $(PATHMAP) $(WARN) -fPIC
CFLAGS_FW   := $(CFLAGS_CORE) -Wfloat-conversion
CFLAGS_HOST := $(CSTD) $(OPT) $(PATHMAP) $(WARN) -D_GNU_SOURCE -fPIC
INC := -Iprotocols/canopen -Iprotocols/coding -Iprotocols/socketcan -Iprotocols/generated -Iplant_rt/blocks -Iplant_rt/models \
       -Iplant_rt/core -Iplant_rt/node -Ifirmware_shim/core -Ifirmware_shim/shim -Ifirmware_shim/port -Iprotocols/faults -Itests/c
# The papers' current laws: law folders as a user's (firmware_shim/laws/<paper>/: C files, headers, law.eds), built
# into every drive; gen_od.py merges their law.eds records (protocols/gen_law.py). Their folders are on the include
# path of the tests and tools that test them; a law's own C files see only their folder and the law interface (LAW_INC).
LAW_DIRS := $(patsubst %/law.eds,%,$(wildcard firmware_shim/laws/*/law.eds))
INC += $(addprefix -I,$(LAW_DIRS))
# A law folder's names: its law.eds's CurrentLaws key (a descriptor current_law_<name> each).
law_names = $(shell sed -n 's/^[[:space:]]*CurrentLaws[[:space:]]*=[[:space:]]*\([A-Za-z0-9_,[:space:]]*\).*/\1/p' \
              '$(1)/law.eds' 2>/dev/null | head -n 1 | tr ',' ' ')
# What a law's C files are compiled with, a paper's as a user's: their own folder (-I$(<D) or -I$(LAW_DIR)) and the law
# interface, firmware_shim/core (current_law.h, dq_math.h, drive_config.h) and the generated OD fields it includes.
LAW_INC = $(filter -I$(GEN_DIR) -Iprotocols/generated -Ifirmware_shim/core,$(INC))
# The checks of a law folder's objects, a paper's as a user's: each name's descriptor defined (nm; $(1) names,
# $(2) objects, $(3) who), and the members the drive calls unconditionally filled with a state that fits (law_check.c;
# $(1) names, $(2) who, $(3) the check program's name: the papers' and a user's law apart, for make -j).
law_nm_check = for n in $(1); do nm $(2) | grep -Eq " [RDBGS] current_law_$$n\$$" || { echo "make: $(3): no C file \
	of the folder defines the symbol current_law_$$n (const current_law_t current_law_$$n = {...};)" >&2; exit 1; }; done
law_check_run = for n in $(1); do rm -f $(BUILD)/$(3).err; \
	$(CC) $(CFLAGS_HOST) $(INC) -DLAW_NAME=$$n firmware_shim/law/law_check.c $(LIBFW) -lm -o $(BUILD)/bin/$(3) \
	2> $(BUILD)/$(3).err && $(BUILD)/bin/$(3) 2> $(BUILD)/$(3).err || { \
	sed 's|^law_check: |make: $(2): |' $(BUILD)/$(3).err >&2; exit 1; }; done

# The FMU loader (plant_rt/fmu/: host glue, dlopen): the FMI 2.0/3.0 co-simulation interface it calls is declared
# by its own plant_rt/fmu/plant_fmi_api.h (no external FMI header), so it is always built, with our warnings.
FMU_SRC := $(wildcard plant_rt/fmu/*.c)
INC += -Iplant_rt/fmu

CO_SRC    := $(wildcard protocols/canopen/*.c) $(wildcard protocols/generated/od_*.c)
SCAN_SRC  := $(wildcard protocols/socketcan/*.c)
PLANT_SRC := $(wildcard plant_rt/blocks/*.c plant_rt/core/*.c plant_rt/models/*/*.c)
FW_SRC    := $(wildcard firmware_shim/core/*.c) $(foreach d,$(LAW_DIRS),$(wildcard $(d)/*.c)) \
             protocols/generated/current_law_table.c
# The node apps: every source of their folders but the process's main (a node app is portable glue).
SHIM_APP_SRC  := $(filter-out firmware_shim/shim/drive_node_main.c,$(wildcard firmware_shim/shim/*.c))
PLANT_APP_SRC := $(filter-out plant_rt/node/plant_node_main.c,$(wildcard plant_rt/node/*.c))
# The fault injector between the plant's and the drive's side (portable core + its rule text).
FAULT_SRC := protocols/faults/fault_injector.c protocols/faults/fault_rules.c

# A user's law: its name from law.eds's CurrentLaws key; gen_od.py --law merges law.eds into drive.eds and
# writes $(BUILD)/eds and $(BUILD)/generated, which replace protocols/generated (first on the include path);
# the law's C files join the firmware (every drive target), compiled as the firmware with its folder on the
# include path.
ifneq ($(strip $(LAW)),)
ifneq ($(words $(LAW)),1)
$(error LAW=$(LAW): a path with white space, which make cannot take: link the folder from a path without (ln -s '<folder>' /tmp/my_law; make LAW=/tmp/my_law))
endif
LAW_DIR  := $(patsubst %/,%,$(strip $(LAW)))
LAW_NAMES := $(call law_names,$(LAW_DIR))
LAW_NAME := $(firstword $(LAW_NAMES))
ifeq ($(LAW_NAME),)
$(error LAW=$(LAW): no $(LAW_DIR)/law.eds with a CurrentLaws=<law name> key)
endif
LAW_SRC  := $(wildcard $(LAW_DIR)/*.c)
ifeq ($(LAW_SRC),)
$(error LAW=$(LAW): no C file in $(LAW_DIR) (it must define const current_law_t current_law_$(LAW_NAME)))
endif
BUILD    ?= build/laws/$(LAW_NAME)
GEN_DIR  := $(BUILD)/generated
GEN_STAMP := $(GEN_DIR)/.stamp
# The folder this build was made from: another folder with the same law name rebuilds the law's files.
LAW_FROM := $(BUILD)/law.from
# (its objects and their dependency files, which name the other folder's files, are dropped first).
$(shell mkdir -p '$(BUILD)' && { [ "$$(cat '$(LAW_FROM)' 2>/dev/null)" = '$(abspath $(LAW_DIR))' ] || { \
        rm -rf '$(BUILD)/obj/law' '$(BUILD)/mcu/obj/law' && echo '$(abspath $(LAW_DIR))' > '$(LAW_FROM)'; }; })
LAW_OK   := $(BUILD)/law.ok
LAW_CHECKED := $(BUILD)/law.checked
INC      := -I$(GEN_DIR) $(filter-out -Iprotocols/generated,$(INC))
CO_SRC   := $(patsubst protocols/generated/%,$(GEN_DIR)/%,$(CO_SRC))
FW_SRC   := $(patsubst protocols/generated/%,$(GEN_DIR)/%,$(FW_SRC)) $(LAW_SRC)
.DEFAULT_GOAL := law
else
BUILD    ?= build
endif

obj = $(patsubst %.c,$(BUILD)/obj/%.o,$(filter-out $(LAW_SRC),$(1))) \
      $(patsubst $(LAW_DIR)/%.c,$(BUILD)/obj/law/%.o,$(filter $(LAW_SRC),$(1)))

LIBCO    := $(BUILD)/libco.a
LIBSCAN  := $(BUILD)/libco_socketcan.a
LIBPLANT := $(BUILD)/libplant.a
LIBFW    := $(BUILD)/libfw.a

# Executables: tools and unit tests of each component.
PROTO_TOOLS := $(patsubst protocols/tools/%.c,$(BUILD)/bin/%,$(wildcard protocols/tools/*.c))
PROTO_TESTS := $(patsubst protocols/tests/%.c,$(BUILD)/tests/protocols_%,$(wildcard protocols/tests/test_*.c)) \
               $(BUILD)/tests/protocols_test_fault_injector $(BUILD)/tests/protocols_test_co_pdo_fd_classic
PLANT_TOOLS := $(patsubst plant_rt/tools/%.c,$(BUILD)/bin/%,$(wildcard plant_rt/tools/*.c))
PLANT_TESTS := $(patsubst plant_rt/tests/%.c,$(BUILD)/tests/plant_%,$(wildcard plant_rt/tests/test_*.c))
FW_TOOLS    := $(patsubst firmware_shim/tools/%.c,$(BUILD)/bin/%,$(wildcard firmware_shim/tools/*.c))
FW_TESTS    := $(patsubst firmware_shim/tests/%.c,$(BUILD)/tests/fw_%,$(wildcard firmware_shim/tests/test_*.c))
NODE_BINS   := $(if $(wildcard plant_rt/node/*.c),$(BUILD)/bin/plant_node) \
               $(if $(wildcard firmware_shim/shim/*.c),$(BUILD)/bin/drive_node) $(BUILD)/bin/fault_gateway
SHLIB       := $(if $(PLANT_SRC)$(FW_SRC),$(BUILD)/libhil.so)

.PHONY: all clean demo test setup fuzz format mcu sanitize law package soak

# The drive firmware as a bare-metal Cortex-M4F image (QEMU mps2-an386; docs/PORTING.md):
# the portable CANopen slave, drive app and cores, the port layer (firmware_shim/port)
# and the board (firmware_shim/mcu/mps2_an386).  Part of `all` when arm-none-eabi-gcc is
# installed (scripts/setup.sh).  -ffp-contract=off: no fused multiply-add, so the image
# computes what the host build computes (also the default of -std=c11; said explicitly).
MCU_CC    := arm-none-eabi-gcc
MCU_DIR   := firmware_shim/mcu/mps2_an386
MCU_BUILD := $(BUILD)/mcu
MCU_ARCH  := -mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard
MCU_CFLAGS := $(MCU_ARCH) -O2 -g $(PATHMAP) $(CSTD) $(WARN) -Wfloat-conversion -ffp-contract=off -DCO_FRAME_MAX_DATA=8u \
              -ffunction-sections -fdata-sections -ffreestanding -fno-common
MCU_INC   := $(INC) -I$(MCU_DIR)
MCU_SRC   := $(CO_SRC) $(FW_SRC) $(SHIM_APP_SRC) $(wildcard firmware_shim/port/*.c) \
             $(wildcard $(MCU_DIR)/*.c)
MCU_OBJ   := $(patsubst %.c,$(MCU_BUILD)/obj/%.o,$(filter-out $(LAW_SRC),$(MCU_SRC))) \
             $(patsubst $(LAW_DIR)/%.c,$(MCU_BUILD)/obj/law/%.o,$(filter $(LAW_SRC),$(MCU_SRC)))
MCU_ELF   := $(MCU_BUILD)/drive_mcu.elf
HAVE_MCU_CC := $(shell command -v $(MCU_CC) 2>/dev/null)

mcu: $(MCU_ELF) $(MCU_BUILD)/drive_mcu.bin
$(MCU_BUILD)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(MCU_CC) $(MCU_CFLAGS) $(MCU_INC) -MMD -MP -c $< -o $@
$(MCU_BUILD)/obj/firmware_shim/laws/%.o: firmware_shim/laws/%.c
	@mkdir -p $(@D)
	$(MCU_CC) $(MCU_CFLAGS) $(LAW_INC) -I$(<D) -MMD -MP -c $< -o $@
$(MCU_ELF): $(MCU_OBJ) $(MCU_DIR)/mps2_an386.ld
	$(MCU_CC) $(MCU_ARCH) -T $(MCU_DIR)/mps2_an386.ld -nostartfiles --specs=nano.specs --specs=nosys.specs \
	    -Wl,--gc-sections -Wl,-Map=$(MCU_BUILD)/drive_mcu.map $(MCU_OBJ) -lm -o $@
	arm-none-eabi-size $@
$(MCU_BUILD)/drive_mcu.bin: $(MCU_ELF)
	arm-none-eabi-objcopy -O binary $< $@

# libFuzzer harness of the CANopen slave (clang, ASan + UBSan).
FUZZ_CFLAGS := -std=c11 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all $(WARN)
fuzz: $(BUILD)/fuzz/fuzz_slave
$(BUILD)/fuzz/fuzz_slave: protocols/fuzz/fuzz_slave.c $(CO_SRC) $(wildcard protocols/canopen/*.h)
	@mkdir -p $(@D)
	clang $(FUZZ_CFLAGS) $(INC) protocols/fuzz/fuzz_slave.c $(CO_SRC) -o $@
# The node processes and the fault gateway with AddressSanitizer and UndefinedBehaviorSanitizer
# (build/sanitize/bin; the bench uses them with BENCH_BIN_DIR=build/sanitize/bin): the fault tests run
# them, so that a fault that drives a node into a bad memory access or undefined behaviour fails.
SAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer -O1 -g
SAN_DIR   := $(BUILD)/sanitize/bin
SAN_NODE_SRC := $(CO_SRC) $(SCAN_SRC)
sanitize: $(SAN_DIR)/plant_node $(SAN_DIR)/drive_node $(SAN_DIR)/fault_gateway
$(SAN_DIR)/plant_node: $(SAN_NODE_SRC) $(PLANT_SRC) $(wildcard plant_rt/node/*.c) $(FMU_SRC) \
    $(wildcard plant_rt/*/*.h protocols/*/*.h)
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) -D_GNU_SOURCE $(SAN_FLAGS) $(INC) $(filter %.c,$^) -lm -ldl -pthread -o $@
$(SAN_DIR)/drive_node: $(SAN_NODE_SRC) $(FW_SRC) $(wildcard firmware_shim/shim/*.c) \
    $(wildcard firmware_shim/*/*.h firmware_shim/laws/*/*.h protocols/*/*.h)
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) -D_GNU_SOURCE $(SAN_FLAGS) $(INC) $(filter %.c,$^) -lm -o $@
$(SAN_DIR)/fault_gateway: protocols/faults/fault_gateway_main.c $(FAULT_SRC) protocols/socketcan/co_socketcan.c $(wildcard protocols/*/*.h)
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) -D_GNU_SOURCE $(SAN_FLAGS) $(INC) $(filter %.c,$^) -o $@

all: $(LIBCO) $(LIBSCAN) $(PROTO_TOOLS) $(PROTO_TESTS) $(PLANT_TOOLS) $(PLANT_TESTS) \
     $(FW_TOOLS) $(FW_TESTS) $(NODE_BINS) $(SHLIB) $(if $(HAVE_MCU_CC),mcu) sanitize $(BUILD)/laws.checked

# What an installed package runs (setup.py makes it at install time in the package's copy of the sources,
# bench/_root): the node processes, the gateway, libhil.so, the tools, the MCU image when its toolchain is there.
package: $(NODE_BINS) $(SHLIB) $(PROTO_TOOLS) $(PLANT_TOOLS) $(FW_TOOLS) $(if $(HAVE_MCU_CC),mcu)

setup:
	@bash scripts/setup.sh

demo: setup
	@.venv/bin/bench demo

test: setup
	@bash scripts/run_tests.sh

# The soak (docs/CI.md): the comparing vcan tests in a loop under busy loops, counting false verdicts.
# make soak SOAK_ARGS="--rounds 5 --tests 30 --suite 3"
SOAK_ARGS ?=
soak: setup
	@.venv/bin/python scripts/soak.py $(SOAK_ARGS)

# The hand-written C (protocols/generated is gen_od.py's: its .clang-format turns formatting off).
STYLE_C = $(shell find firmware_shim plant_rt protocols bench/direct -name '*.[ch]' -not -path 'protocols/generated/*')
format:
	.venv/bin/ruff format .
	clang-format -i --style=file $(STYLE_C)

$(BUILD)/obj/protocols/socketcan/%.o: protocols/socketcan/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/protocols/tools/%.o: protocols/tools/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/plant_rt/node/%.o: plant_rt/node/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/plant_rt/fmu/%.o: plant_rt/fmu/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/firmware_shim/shim/%.o: firmware_shim/shim/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/firmware_shim/%.o: firmware_shim/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_FW) $(INC) -MMD -MP -c $< -o $@
$(BUILD)/obj/firmware_shim/laws/%.o: firmware_shim/laws/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_FW) $(LAW_INC) -I$(<D) -MMD -MP -c $< -o $@
# The papers' law folders checked as `make LAW=DIR` checks a user's (law_nm_check, law_check_run).
$(BUILD)/laws.checked: firmware_shim/law/law_check.c $(LIBFW)
	@mkdir -p $(BUILD)/bin
	@$(foreach d,$(LAW_DIRS),$(call law_nm_check,$(call law_names,$(d)),$(call obj,$(wildcard $(d)/*.c)),$(d)) && \
	  $(call law_check_run,$(call law_names,$(d)),$(d),law_check_papers) && ) true
	@touch $@
$(BUILD)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_CORE) $(INC) -MMD -MP -c $< -o $@

$(LIBCO): $(call obj,$(CO_SRC))
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^
$(LIBSCAN): $(call obj,$(SCAN_SRC))
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^
$(LIBPLANT): $(call obj,$(PLANT_SRC))
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^
$(LIBFW): $(call obj,$(FW_SRC))
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^

$(BUILD)/bin/%: protocols/tools/%.c $(LIBSCAN) $(LIBCO)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) $< $(LIBSCAN) $(LIBCO) -lm -o $@
$(BUILD)/tests/protocols_%: protocols/tests/%.c $(LIBCO)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(LIBCO) -lm -o $@
$(BUILD)/bin/%: plant_rt/tools/%.c $(LIBPLANT)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) $< $(LIBPLANT) -lm -o $@
$(BUILD)/tests/plant_%: plant_rt/tests/%.c $(LIBPLANT)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(LIBPLANT) -lm -o $@
# Tests of the node apps need the CANopen core and the portable app glue too.
# The drive tests close the loop against the plant's own motor model (tests/c/motor_model.h): libplant.
# The apps are linked as objects (built with their own dependency files): one source per compile line,
# so that -MF records the test's own headers (with several sources, gcc keeps the last one's only).
SHIM_APP_OBJ  := $(call obj,$(SHIM_APP_SRC))
PLANT_APP_OBJ := $(call obj,$(PLANT_APP_SRC))
$(BUILD)/tests/fw_test_shim_%: firmware_shim/tests/test_shim_%.c $(SHIM_APP_OBJ) $(LIBFW) $(LIBPLANT) $(LIBCO)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(SHIM_APP_OBJ) $(LIBFW) $(LIBPLANT) $(LIBCO) -lm -o $@
$(BUILD)/tests/plant_test_node_%: plant_rt/tests/test_node_%.c $(PLANT_APP_OBJ) $(LIBPLANT) $(LIBCO)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(PLANT_APP_OBJ) $(LIBPLANT) $(LIBCO) -lm -o $@
$(BUILD)/bin/%: firmware_shim/tools/%.c $(LIBFW)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $(INC) $< $(LIBFW) -lm -o $@
# The SLCAN codec of the port layer (portable, host-tested).
$(BUILD)/tests/fw_test_slcan: firmware_shim/tests/test_slcan.c firmware_shim/port/slcan.c
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_FW) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $^ -o $@
$(BUILD)/tests/fw_%: firmware_shim/tests/%.c $(LIBFW) $(LIBPLANT)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(LIBFW) $(LIBPLANT) -lm -o $@

$(BUILD)/bin/plant_node: $(call obj,$(wildcard plant_rt/node/*.c) $(FMU_SRC)) $(LIBPLANT) $(LIBSCAN) $(LIBCO)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $^ -lm -ldl -pthread -o $@
$(BUILD)/bin/drive_node: $(call obj,$(wildcard firmware_shim/shim/*.c)) $(LIBFW) $(LIBSCAN) $(LIBCO)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) $^ -lm -o $@
# The injector's unit test, with the sanitizers (its hold queue and log are fixed arrays).
$(BUILD)/tests/protocols_test_fault_injector: protocols/faults/tests/test_fault_injector.c $(FAULT_SRC)
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) $(SAN_FLAGS) $(INC) $^ -o $@
# The CAN FD test against the CANopen core built as the Cortex-M4F image builds it (8-byte frames), with the
# sanitizers: the classic-only node refuses CAN FD, and no copy runs past its frames.
$(BUILD)/tests/protocols_test_co_pdo_fd_classic: protocols/tests/test_co_pdo_fd.c $(CO_SRC)
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) $(SAN_FLAGS) -DCO_FRAME_MAX_DATA=8u $(INC) $^ -lm -o $@
# The fault injector as a SocketCAN gateway process (side a <-> side b).
$(BUILD)/bin/fault_gateway: protocols/faults/fault_gateway_main.c $(FAULT_SRC) $(LIBSCAN)
	@mkdir -p $(@D) $(BUILD)/deps
	$(CC) $(CFLAGS_HOST) $(INC) -MMD -MP -MF $(BUILD)/deps/$(@F).d $< $(FAULT_SRC) $(LIBSCAN) -o $@
HIL_SRC := $(PLANT_SRC) $(FW_SRC) $(CO_SRC) $(PLANT_APP_SRC) $(SHIM_APP_SRC) $(wildcard bench/direct/*.c) $(FAULT_SRC) \
           $(FMU_SRC)
$(BUILD)/libhil.so: $(call obj,$(HIL_SRC))
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_HOST) -shared $^ -lm -ldl -pthread -o $@  # the flags: -flto compiles here (-ffile-prefix-map too)

clean:
	rm -rf $(BUILD)

ifneq ($(strip $(LAW)),)
# What a run with the law needs (bench ... --law DIR): the nodes, the gateway, libhil.so, the MCU image.
law: $(LAW_OK) $(LAW_CHECKED) $(BUILD)/bin/drive_node $(BUILD)/bin/plant_node $(BUILD)/bin/fault_gateway $(BUILD)/libhil.so \
     $(if $(HAVE_MCU_CC),mcu)
	@echo "make: law $(LAW_NAME) built in $(BUILD)"
$(GEN_STAMP): $(LAW_DIR)/law.eds $(LAW_FROM) $(wildcard protocols/eds/*.eds) protocols/eds/common.ini \
    $(wildcard firmware_shim/laws/*/law.eds) \
    protocols/gen_od.py $(wildcard protocols/odgen/*.py) protocols/gen_law.py protocols/eds_reader.py
	$(PYTHON) protocols/gen_od.py --law '$(LAW_DIR)' --out '$(BUILD)'
	@touch $@
$(addprefix $(GEN_DIR)/,od_drive.h od_drive.c od_drive_fields.h od_plant.h od_plant.c od_plant_fields.h \
    eds_common.h current_law_table.c): $(GEN_STAMP) ;
# Every object after the generated headers (their .d files take over from the second build on).
$(call obj,$(CO_SRC) $(SCAN_SRC) $(PLANT_SRC) $(FW_SRC) $(HIL_SRC) $(wildcard firmware_shim/shim/*.c plant_rt/node/*.c) \
    protocols/faults/fault_gateway_main.c) $(MCU_OBJ): | $(GEN_STAMP)
$(BUILD)/obj/law/%.o: $(LAW_DIR)/%.c $(LAW_FROM)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_FW) $(LAW_INC) -I$(LAW_DIR) -MMD -MP -c $< -o $@
$(MCU_BUILD)/obj/law/%.o: $(LAW_DIR)/%.c $(LAW_FROM)
	@mkdir -p $(@D)
	$(MCU_CC) $(MCU_CFLAGS) $(LAW_INC) -I$(LAW_DIR) -MMD -MP -c $< -o $@
# The folder must define the descriptor each of its names promises (current_law_table.c refers to it).
$(LAW_OK): $(call obj,$(LAW_SRC))
	@$(call law_nm_check,$(LAW_NAMES),$^,LAW=$(LAW))
	@touch $@
$(LIBFW) $(BUILD)/libhil.so $(MCU_ELF): | $(LAW_OK)
# ... and fills the members the drive calls unconditionally, with a state that fits (firmware_shim/law/law_check.c).
$(LAW_CHECKED): firmware_shim/law/law_check.c $(LIBFW)
	@mkdir -p $(BUILD)/bin
	@$(call law_check_run,$(LAW_NAMES),LAW=$(LAW),law_check)
	@touch $@
$(BUILD)/bin/drive_node $(BUILD)/libhil.so $(MCU_ELF): | $(LAW_CHECKED)
endif

-include $(shell find $(BUILD)/obj $(BUILD)/deps $(BUILD)/mcu/obj -name '*.d' 2>/dev/null)
endif  # LAW_HANDED
