# surfd - one plain Makefile (STYLE.md §12).
#   make            build/surfd (release)
#   make run        install missing Debian packages, build, serve on 127.0.0.1:8080 (PORT=N: port N) with the store in ./var
#   make install    binary, systemd unit and config (DESTDIR and PREFIX respected)
#   make check      unit tests, thread-sanitizer tests, fuzz replays and torture (every allocation of
#                   the fuzz seeds refused in turn): a few minutes, for every change
#   make test       make check's and the black-box suites (API, CLI, page in a browser, package): what CI runs;
#                   last line "N passed, N failed"
#   make bench      benchmarks against POV-Ray and surfd's own mesh method -> tests/bench/RESULTS.md
#   make layers     check the include rules between core/'s folders, api/ and daemon/ (make check also
#                   checks that no files call or include each other in a circle: tests/tools/circles.sh)
#   make fuzz       every decoder's libFuzzer target for FUZZ_SECONDS (60) each (its crashers replayed by check)
#   make deb        build/surfd_VERSION_amd64.deb (deploy/deb.sh)
# Warnings are errors when CI=true (or WERROR=1).

CC      ?= cc
CXX     ?= c++
B       := build
VERSION := $(shell git describe --always --dirty 2>/dev/null || echo dev)

WARN    := -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes
ifneq ($(filter true 1,$(CI) $(WERROR)),)
WARN    += -Werror
endif
CSTD    := -std=c11 -D_DEFAULT_SOURCE -I/usr/include/postgresql -I/usr/include/openjpeg-2.5
OPT     ?= -O2 -g
CFLAGS  := $(CSTD) $(OPT) $(WARN) -MMD -MP -DSURFD_VERSION='"$(VERSION)"'
CXXFLAGS:= -std=c++17 $(OPT) -Wall -Wextra -MMD -MP
SAN     := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
TSAN    := -fsanitize=thread

CORE_LIBS := -lembree3 -lm
API_LIBS  := -ljansson -lz -lopenjp2
DAEMON_LIBS := -lmicrohttpd -lsqlite3 -lpq -lgnutls -lcurl -lpthread
IMG_LIBS  := -lOpenImageIO -lOpenImageIO_Util -lstdc++
DCM_LIBS  := -ldcmjpls -ldcmjpeg -ldcmimgle -ldcmdata -loflog -lofstd -lstdc++

# sources by wildcard: core/ by layer (tests/tools/layers.sh), api/'s C++ shims linked on their own
CORE_SRC   := $(wildcard core/*/*.c)
API_SRC    := $(wildcard api/*.c)
DAEMON_SRC := $(wildcard daemon/*.c)
TEST_SRC   := $(wildcard tests/core/*/test_*.c) $(wildcard tests/api/test_*.c)
TSAN_TESTS := $(B)/tests/daemon/test_jobq $(B)/tests/core/matrix/tsan_fragments $(B)/tests/core/trace/tsan_map
TESTS_MORE := $(B)/tests/daemon/test_memwrap $(B)/tests/daemon/test_store

obj = $(patsubst %.c,$(B)/$(1)/%.o,$(2))

# fuzz targets (tests/fuzz/fuzz_NAME.c): replayed over their seeds and crashers by make test (gcc,
# sanitizers, tests/fuzz/replay.c), fuzzed with libFuzzer by make fuzz and, briefly, by make test
FUZZ_TARGETS := $(patsubst tests/fuzz/fuzz_%.c,%,$(wildcard tests/fuzz/fuzz_*.c))
FUZZ_DAEMON  := daemon/config.c daemon/tokens.c
REPLAYS      := $(patsubst %,$(B)/tests/fuzz/replay_%,$(FUZZ_TARGETS))
TORTURES     := $(patsubst %,$(B)/tests/fuzz/torture_%,$(FUZZ_TARGETS))
FUZZERS      := $(patsubst %,$(B)/fuzz/%,$(FUZZ_TARGETS))
FUZZ_CC      := clang
FUZZ_FLAGS   := -g -O1 -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
FUZZ_SECONDS ?= 60

REL_CORE := $(call obj,rel,$(CORE_SRC))
REL_API  := $(call obj,rel,$(API_SRC))
REL_DMN  := $(call obj,rel,$(DAEMON_SRC))
SAN_CORE := $(call obj,san,$(CORE_SRC))
SAN_API  := $(call obj,san,$(API_SRC))
TESTS    := $(patsubst tests/%.c,$(B)/tests/%,$(TEST_SRC))

.PHONY: all run check test bench clean deps install fuzz layers deb
all: layers $(B)/surfd $(B)/surfctl

# the one-way include rules of core/ and api/
layers:
	@tests/tools/layers.sh

# (the formats' table: surfctl sends a file's type as the daemon reads it)
$(B)/surfctl: $(B)/rel/client/surfctl.o $(B)/rel/api/formats.o $(B)/rel/api/dicom_scan.o $(B)/rel/api/nifti.o $(B)/rel/core/base/err.o
	$(CC) $(OPT) -o $@ $^ -lcurl -ljansson -lz -lm

deps:
	@deploy/install-deps.sh

$(B)/rel/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -c $< -o $@
# the tracer's inner loops (core/trace, core/geom) at -O3: the teapot's render 2 % faster, the
# pictures the same bits (no contraction under -std=c11); the rest stays at -O2
$(B)/rel/core/trace/%.o $(B)/rel/core/geom/%.o $(B)/rel/core/iso/mc.o $(B)/rel/core/iso/kept.o: CFLAGS += -O3
# the release build leaves out the asserts of the daemon's threading contracts (daemon/jobq.c);
# the sanitizer and test builds keep them
$(B)/rel/%.o: CFLAGS += -DNDEBUG
$(B)/san/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) -c $< -o $@
$(B)/rel/api/%.o: api/%.cpp
	@mkdir -p $(@D)
	$(CXX) $(CXXFLAGS) -c $< -o $@
# OpenImageIO's shim, a shared object the programs load on their first image (api/image.h)
$(B)/pic/image_oiio.o: api/image_oiio.cpp
	@mkdir -p $(@D)
	$(CXX) $(CXXFLAGS) -fPIC -c $< -o $@
$(B)/pic/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -fPIC -c $< -o $@
$(B)/libsurfd-image.so: $(B)/pic/image_oiio.o $(B)/pic/core/base/err.o
	$(CXX) -shared -Wl,-z,defs -o $@ $^ $(IMG_LIBS)
$(B)/san/libsurfd-image.so: $(B)/libsurfd-image.so
	@mkdir -p $(@D)
	ln -sf ../libsurfd-image.so $@
DCM_SRC := $(wildcard api/*_dcmtk.cpp) # the DCMTK shims: RT Structure Sets, image series
DCM_OBJ := $(patsubst %.cpp,$(B)/rel/%.o,$(DCM_SRC))
# the daemon's own: the DICOM node's SCP (dcmnet), linked into surfd alone
DMN_DCM_OBJ := $(patsubst %.cpp,$(B)/rel/%.o,$(wildcard daemon/*_dcmtk.cpp))
$(B)/rel/daemon/%.o: daemon/%.cpp
	@mkdir -p $(@D)
	$(CXX) $(CXXFLAGS) -c $< -o $@

# api/openapi.yaml, served at /openapi.yaml, compiled in as a C string
$(B)/gen/openapi.c: api/openapi.yaml
	@mkdir -p $(@D)
	@{ echo 'const char surfd_openapi_yaml[] = {'; od -An -v -tx1 $< | sed 's/ *\([0-9a-f][0-9a-f]\)/0x\1,/g'; echo '0};'; } >$@
$(B)/gen/openapi.o: $(B)/gen/openapi.c
	$(CC) -c $< -o $@

# the page's 3D view: client/web/view.js bundled with three.js by esbuild, both from npm at the
# versions client/web/package-lock.json pins, installed into $(B)/web (none of their code in the
# repository; the build needs the npm registry once, the running daemon never: client/web/README.md)
WEB_NPM := $(B)/web/node_modules/.installed
$(WEB_NPM): client/web/package.json client/web/package-lock.json
	@mkdir -p $(B)/web
	cp client/web/package.json client/web/package-lock.json $(B)/web/
	cd $(B)/web && npm ci --no-audit --no-fund --loglevel=error
	@touch $@
$(B)/web/view.js: client/web/view.js client/web/mesh_delta.js client/web/slices.js client/web/live.js $(WEB_NPM)
	NODE_PATH=$(B)/web/node_modules $(B)/web/node_modules/.bin/esbuild client/web/view.js --bundle --minify \
		--format=esm --target=es2020 --log-level=warning --outfile=$@

# the web page (client/web/ and the bundle), served at / and its files' names, compiled in (daemon/assets.h)
WEB := client/web/index.html client/web/app.js client/web/style.css $(B)/web/view.js
$(B)/gen/web.c: $(WEB) Makefile
	@mkdir -p $(@D)
	@{ echo '#include "daemon/assets.h"'; k=0; for f in $(WEB); do \
		echo "static const char f$$k[] = {"; od -An -v -tx1 $$f | sed 's/ *\([0-9a-f][0-9a-f]\)/0x\1,/g'; echo '0};'; \
		k=$$((k + 1)); done; echo 'const struct asset surfd_assets[] = {'; k=0; for f in $(WEB); do \
		case $$f in *.html) t='text/html; charset=utf-8'; p=/ ;; *.js) t='text/javascript; charset=utf-8'; p=/$${f##*/} ;; \
		*.css) t='text/css; charset=utf-8'; p=/$${f##*/} ;; esac; \
		echo "    {\"$$p\", \"$$t\", f$$k, sizeof f$$k - 1},"; k=$$((k + 1)); done; echo '    {0}};'; } >$@
$(B)/gen/web.o: $(B)/gen/web.c daemon/assets.h
	$(CC) -I. -c $< -o $@

# the daemon's own allocations charged to the job a thread works for (daemon/memwrap.c)
MEMWRAP := -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=strdup,--wrap=free
$(B)/surfd: $(REL_DMN) $(REL_API) $(DCM_OBJ) $(DMN_DCM_OBJ) $(B)/gen/openapi.o $(B)/gen/web.o $(REL_CORE) | $(B)/libsurfd-image.so
	$(CC) $(OPT) $(MEMWRAP) -o $@ $^ -ldcmnet $(DCM_LIBS) $(DAEMON_LIBS) $(API_LIBS) $(CORE_LIBS)

# unit tests: tests/core/LAYER's link that layer and those below it alone (tests/tools/layers.sh
# --below), so a test of a layer cannot lean on what is above it; tests/api's link core/ and api/
# (with the DCMTK shim), never OpenImageIO: api/'s own tests, and core's on the shared data, which
# they read with api/'s parsers
define layer_tests
$(B)/tests/core/$(1)/%: tests/core/$(1)/%.c tests/unit.h $(call obj,san,$(foreach l,$(shell tests/tools/layers.sh --below $(1)),$(wildcard core/$(l)/*.c)))
	@mkdir -p $$(@D)
	$$(CC) $$(CFLAGS) $$(SAN) -o $$@ $$(filter %.c %.o,$$^) $$(CORE_LIBS)
endef
$(foreach l,base geom trace contour iso matrix,$(eval $(call layer_tests,$(l))))
$(B)/tests/api/%: tests/api/%.c tests/unit.h $(wildcard tests/api/*.h) $(SAN_CORE) $(SAN_API) $(DCM_OBJ)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) -o $@ $< $(SAN_CORE) $(SAN_API) $(DCM_OBJ) $(API_LIBS) $(DCM_LIBS) $(CORE_LIBS)

# a fuzz target with a plain main over files, for make test
$(B)/tests/fuzz/replay_%: tests/fuzz/fuzz_%.c tests/fuzz/replay.c tests/fuzz/util.c tests/fuzz/fuzz.h $(SAN_CORE) $(SAN_API) \
		$(call obj,san,$(FUZZ_DAEMON)) $(DCM_OBJ)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) -o $@ $(filter %.c %.o,$^) $(API_LIBS) $(DCM_LIBS) $(CORE_LIBS)

# ... and with every allocation of an input refused in turn (tests/fuzz/torture.sh)
$(B)/tests/fuzz/torture_%: tests/fuzz/fuzz_%.c tests/fuzz/replay.c tests/fuzz/util.c tests/fuzz/fuzz.h daemon/memwrap.c \
		$(SAN_CORE) $(SAN_API) $(call obj,san,$(FUZZ_DAEMON)) $(DCM_OBJ)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) $(MEMWRAP) -DTORTURE -o $@ $(filter %.c %.o,$^) $(API_LIBS) $(DCM_LIBS) $(CORE_LIBS)

# the same targets under libFuzzer (clang), the DCMTK shim instrumented too
$(B)/fz/%.o: %.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CSTD) $(FUZZ_FLAGS) $(WARN) -MMD -MP -c $< -o $@
$(B)/fz/api/%.o: api/%.cpp
	@mkdir -p $(@D)
	$(FUZZ_CC)++ -std=c++17 $(FUZZ_FLAGS) -Wall -Wextra -MMD -MP -c $< -o $@
FZ_OBJ := $(call obj,fz,$(CORE_SRC) $(API_SRC) $(FUZZ_DAEMON) tests/fuzz/util.c) $(patsubst %.cpp,$(B)/fz/%.o,$(DCM_SRC))
.SECONDARY: $(FZ_OBJ) $(patsubst %,$(B)/fz/tests/fuzz/fuzz_%.o,$(FUZZ_TARGETS)) # kept, not rebuilt each run
$(B)/fuzz/%: $(B)/fz/tests/fuzz/fuzz_%.o $(FZ_OBJ)
	@mkdir -p $(@D)
	$(FUZZ_CC)++ -fsanitize=fuzzer,address,undefined -o $@ $^ $(API_LIBS) $(DCM_LIBS) $(CORE_LIBS)

fuzz: deps $(FUZZERS)
	@FUZZ_SECONDS=$(FUZZ_SECONDS) tests/fuzz/fuzz.sh

# the pool and queue under the thread sanitizer
# the store conformance suite: SQLite here, both backends in tests/api/store_conformance.sh
STORE_SRC := daemon/store.c daemon/store_values.c daemon/store_sqlite.c daemon/store_pg.c daemon/store_walmark.c daemon/job_state.c \
             api/mesh_io.c api/mesh_journal.c core/base/err.c core/base/mem.c core/geom/trimesh.c
$(B)/tests/daemon/test_store: tests/daemon/test_store.c tests/unit.h $(STORE_SRC) $(wildcard daemon/store*.h)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) -o $@ tests/daemon/test_store.c $(STORE_SRC) -lsqlite3 -lpq -lgnutls -lpthread -lm
$(B)/tests/daemon/test_jobq: tests/daemon/test_jobq.c tests/unit.h daemon/jobq.c daemon/jobq.h core/base/mem.c core/base/clock.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(TSAN) -o $@ tests/daemon/test_jobq.c daemon/jobq.c core/base/mem.c core/base/clock.c -lpthread

# the allocator wrappers, linked as the daemon links them
$(B)/tests/daemon/test_memwrap: tests/daemon/test_memwrap.c tests/unit.h daemon/memwrap.c core/base/mem.c core/base/mem.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) $(MEMWRAP) -o $@ tests/daemon/test_memwrap.c daemon/memwrap.c core/base/mem.c -ljansson -lpthread

# matrix_fragments' table, made once a process, under the thread sanitizer
$(B)/tests/core/matrix/tsan_fragments: tests/core/matrix/tsan_fragments.c tests/unit.h core/matrix/fragment.c core/matrix/matrix.h core/geom/trimesh.c core/base/mem.c core/base/err.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(TSAN) -o $@ tests/core/matrix/tsan_fragments.c core/matrix/fragment.c core/geom/trimesh.c core/base/mem.c core/base/err.c -lm -lpthread
# the map's parts on threads (its seams from the test's own table: no hierarchy, no Embree)
TSAN_MAP_SRC := core/trace/map.c core/trace/bvh_cone.c core/geom/tess.c core/geom/bezier.c core/geom/trim.c core/base/mem.c core/base/err.c
$(B)/tests/core/trace/tsan_map: tests/core/trace/tsan_map.c tests/unit.h $(TSAN_MAP_SRC) $(wildcard core/trace/*.h core/geom/*.h)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(TSAN) -o $@ tests/core/trace/tsan_map.c $(TSAN_MAP_SRC) -lm -lpthread

# daemon/dicomweb.c from the command line (tests/api/dicomweb.sh against a real Orthanc), sanitized
DICOMWEB_SRC := daemon/dicomweb.c api/multipart.c core/base/err.c core/base/clock.c
$(B)/tests/tools/dicomweb_tool: tests/tools/dicomweb_tool.c $(DICOMWEB_SRC) daemon/dicomweb.h api/multipart.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(SAN) -o $@ tests/tools/dicomweb_tool.c $(DICOMWEB_SRC) -lcurl -ljansson

# the daemon with the address and UB sanitizers, for the black-box API tests
$(B)/san/surfd: $(call obj,san,$(DAEMON_SRC)) $(SAN_API) $(DCM_OBJ) $(DMN_DCM_OBJ) $(B)/gen/openapi.o $(B)/gen/web.o $(SAN_CORE) | $(B)/san/libsurfd-image.so
	$(CC) $(OPT) $(SAN) $(MEMWRAP) -o $@ $^ -ldcmnet $(DCM_LIBS) $(DAEMON_LIBS) $(API_LIBS) $(CORE_LIBS)

# the port make run serves on: make run PORT=8081
PORT ?= 8080
run: deps $(B)/surfd
	$(B)/surfd serve --listen 127.0.0.1:$(PORT) --data-dir var

PREFIX  ?= /usr/local
install: $(B)/surfd $(B)/surfctl $(B)/libsurfd-image.so
	install -D -m 0755 $(B)/surfd $(DESTDIR)$(PREFIX)/bin/surfd
	install -D -m 0755 $(B)/surfctl $(DESTDIR)$(PREFIX)/bin/surfctl
	install -D -m 0644 $(B)/libsurfd-image.so $(DESTDIR)$(PREFIX)/lib/surfd/libsurfd-image.so
	install -D -m 0644 deploy/surfd.service $(DESTDIR)/etc/systemd/system/surfd.service
	install -D -m 0644 deploy/surfd@.service $(DESTDIR)/etc/systemd/system/surfd@.service
	[ -e $(DESTDIR)/etc/surfd/surfd.conf ] || install -D -m 0640 deploy/surfd.conf $(DESTDIR)/etc/surfd/surfd.conf
	install -D -m 0644 README.md $(DESTDIR)$(PREFIX)/share/doc/surfd/README.md
	install -D -m 0644 LICENSE $(DESTDIR)$(PREFIX)/share/doc/surfd/LICENSE
	install -D -m 0644 api/openapi.yaml $(DESTDIR)$(PREFIX)/share/doc/surfd/openapi.yaml
	@if [ -z "$(DESTDIR)" ] && ! id surfd >/dev/null 2>&1; then \
		useradd --system --home-dir /var/lib/surfd --shell /usr/sbin/nologin surfd; fi
	@echo "installed; start with: systemctl daemon-reload && systemctl enable --now surfd"

# Open CASCADE as the oracle of the IGES tests (tests/tools/occt_iges.cpp), never linked into surfd
OCCT_LIBS := -lTKIGES -lTKXSBase -lTKShHealing -lTKMesh -lTKTopAlgo -lTKGeomAlgo -lTKBRep -lTKGeomBase -lTKG3d -lTKG2d \
             -lTKMath -lTKernel
$(B)/tests/tools/occt_iges: tests/tools/occt_iges.cpp
	@mkdir -p $(@D)
	$(CXX) -O2 -std=c++17 -Wall -Wextra -Werror -isystem /usr/include/opencascade -o $@ $< $(OCCT_LIBS)

# the tiers: what each builds (on every core, once the packages are in) and runs
NPROC      := $(shell nproc 2>/dev/null || echo 2)
# (the objects of core/, api/ and daemon/ for tests/tools/circles.sh: no circle between files)
CHECK_BINS := $(TESTS) $(TESTS_MORE) $(TSAN_TESTS) $(REPLAYS) $(TORTURES) $(SAN_CORE) $(SAN_API) $(call obj,san,$(DAEMON_SRC))
CHECKS     := $(TESTS) $(TESTS_MORE) $(TSAN_TESTS) tests/fuzz/replay.sh tests/fuzz/torture.sh tests/tools/circles.sh
SUITES     := $(wildcard tests/cli/*.sh tests/api/*.sh tests/web/*.sh tests/deploy/*.sh)
check: deps layers
	@$(MAKE) --no-print-directory -j$(NPROC) $(CHECK_BINS)
	@tests/run.sh $(CHECKS)
test: deps layers
	@$(MAKE) --no-print-directory -j$(NPROC) $(CHECK_BINS) $(B)/surfd $(B)/surfctl $(B)/san/surfd $(B)/tests/tools/occt_iges \
		$(B)/tests/tools/dicomweb_tool
	@SURFD_BIN=$(B)/san/surfd tests/run.sh $(CHECKS) $(SUITES)

bench: $(B)/surfd
	@deploy/install-deps.sh --bench
	@tests/bench/run.sh

# a Debian version starts with a digit: 0.1.0+git<commits>.<hash>
DEB_VERSION := 0.1.0+git$(shell git rev-list --count HEAD 2>/dev/null || echo 0).$(shell git rev-parse --short HEAD 2>/dev/null || echo dev)
deb: $(B)/surfd $(B)/surfctl $(B)/libsurfd-image.so
	@deploy/deb.sh $(DEB_VERSION)

clean:
	rm -rf $(B)

-include $(shell find $(B) -name '*.d' 2>/dev/null)
