# tests/vm/vm.mk — build rules for the programs that run inside the check-vm guest (tests/vm/run).
# Read after the Makefile, whose variables it uses (same compiler flags, same library):
#     make -f Makefile -f tests/vm/vm.mk vm-tests
# The programs go to $(BUILD)/vm/, apart from $(BUILD)/tests/ so that `make check` never picks them up.
# --as-needed: only the shared libraries a program really uses are recorded, so the guest's initramfs carries
# libudev, hidapi, libgpiod and cmocka, not OpenImageIO and its dependencies.
VM_SRC := $(wildcard tests/vm/vm_*.c)
VM_BIN := $(VM_SRC:tests/vm/%.c=$(BUILD)/vm/%)

.PHONY: vm-tests
vm-tests: $(VM_BIN)

$(BUILD)/vm/%: tests/vm/%.c $(LIB)
	@mkdir -p $(dir $@)
	$(CC) $(ALL_CFLAGS) -MMD -MP -o $@ $< $(LIB) -Wl,--as-needed $(LDLIBS_ALL) -lcmocka

-include $(VM_BIN:=.d)
