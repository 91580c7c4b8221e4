# core.mk - the portable device core's sources, for every firmware Makefile.
#
# A port's Makefile sets EXO_CORE_DIR (the path of this folder from where make runs)
# and includes this file:
#     EXO_CORE_DIR := ../../core
#     include $(EXO_CORE_DIR)/core.mk
#     CFLAGS += -I$(EXO_CORE_DIR)
# and compiles $(CORE_SRC) with its own sources. The core needs C99 and nothing from
# libc but <stdint.h>, <stddef.h> and <string.h> (memcpy, memset).
EXO_CORE_DIR ?= $(dir $(lastword $(MAKEFILE_LIST)))
CORE_FILES := sha256.c hmac.c wire.c session.c watchdog.c as5048a.c device.c
CORE_SRC := $(addprefix $(EXO_CORE_DIR:%/=%)/,$(CORE_FILES))
CORE_HEADERS := $(wildcard $(EXO_CORE_DIR:%/=%)/*.h)
