# Build step of CMakeLists.txt (cmake -P): build hocurve with cargo and stage
# the files under the names they are installed with:
#
#   STAGE/lib/libhocurve.so.X.Y.Z  (SONAME given: libhocurve.so.X, or .0.Y while X = 0), its two links
#   STAGE/lib/libhocurve.a         exporting only the hoc_* functions
#   STAGE/bin/hocurve              (BUILD_CLI)
#
# Input (-D): CARGO MANIFEST TARGET_DIR STAGE VERSION SONAME BUILD_CLI
#             NATIVE_LIBS C_COMPILER OBJCOPY AR READELF
#
# A staged file is rewritten only when cargo's output changed, so a no-op
# build relinks nothing downstream.
cmake_minimum_required(VERSION 3.20)

foreach(v CARGO MANIFEST TARGET_DIR STAGE VERSION SONAME C_COMPILER OBJCOPY AR READELF)
  if(NOT DEFINED ${v} OR "${${v}}" STREQUAL "")
    message(FATAL_ERROR "hocurve_stage.cmake: ${v} not given")
  endif()
endforeach()
set(release "${TARGET_DIR}/release")
file(MAKE_DIRECTORY "${STAGE}/lib" "${STAGE}/bin" "${STAGE}/tmp")

# 1. The shared library, the rlib and the command-line tool.
set(what --lib)
if(BUILD_CLI)
  list(APPEND what --bin hocurve)
endif()
execute_process(
  COMMAND "${CARGO}" build --release ${what} --manifest-path "${MANIFEST}" --target-dir "${TARGET_DIR}"
  RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "hocurve: cargo build failed (exit ${rc})")
endif()

# 2. The static library, built alone so that rustc prints the native libraries
#    it needs. Cargo keeps this build (a staticlib-only crate type) apart from
#    the one above: each stays up to date, neither rebuilds the other. The
#    crate itself compiles a second time after a source change (~30 s).
execute_process(
  COMMAND "${CARGO}" rustc --release --lib --crate-type staticlib --message-format=json
          --manifest-path "${MANIFEST}" --target-dir "${TARGET_DIR}" -- --print native-static-libs
  RESULT_VARIABLE rc OUTPUT_VARIABLE json)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "hocurve: cargo rustc --crate-type staticlib failed (exit ${rc})")
endif()
if(NOT json MATCHES "\"message\":\"native-static-libs: ([^\"]*)\"")
  message(FATAL_ERROR "hocurve: rustc printed no native-static-libs line")
endif()
string(STRIP "${CMAKE_MATCH_1}" native)
# The link line CMake configured (the hocurve::hocurve_static target, the
# installed hocurveConfig.cmake and hocurve.pc) must be this one.
if(NOT native STREQUAL NATIVE_LIBS)
  message(FATAL_ERROR "hocurve: libhocurve.a needs \"${native}\" (rustc --print native-static-libs) but CMake "
                      "was configured with \"${NATIVE_LIBS}\"; reconfigure with -DHOCURVE_NATIVE_STATIC_LIBS=\"${native}\"")
endif()
set(archive "")
if(json MATCHES "\"crate_types\":\\[\"staticlib\"\\][^\n]*\"filenames\":\\[\"([^\"]*\\.a)\"\\]")
  set(archive "${CMAKE_MATCH_1}")
endif()
if(archive STREQUAL "" OR NOT EXISTS "${archive}")
  message(FATAL_ERROR "hocurve: cargo reported no static library ('${archive}')")
endif()

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_VARIABLE out)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${ARGN}")
    message(FATAL_ERROR "hocurve: failed (exit ${rc}): ${cmd}\n${out}${err}")
  endif()
endfunction()

# 3. libhocurve.so.X.Y.Z with its two links. build.rs gives it the SONAME.
set(so_real "libhocurve.so.${VERSION}")
# SONAME: the ABI version's name, computed by CMakeLists.txt like build.rs does.
set(so_major "${SONAME}")
run("${CMAKE_COMMAND}" -E copy_if_different "${release}/libhocurve.so" "${STAGE}/lib/${so_real}")
execute_process(COMMAND "${READELF}" -d "${STAGE}/lib/${so_real}" OUTPUT_VARIABLE dyn RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT dyn MATCHES "\\(SONAME\\)[^\n]*\\[${so_major}\\]")
  message(FATAL_ERROR "hocurve: ${release}/libhocurve.so has no SONAME ${so_major} (build.rs sets it)")
endif()
foreach(link_target IN ITEMS "${so_major}=${so_real}" "libhocurve.so=${so_major}")
  string(REPLACE "=" ";" pair "${link_target}")
  list(GET pair 0 name)
  list(GET pair 1 points_to)
  if(IS_SYMLINK "${STAGE}/lib/${name}")
    file(READ_SYMLINK "${STAGE}/lib/${name}" current)
  else()
    set(current "")
  endif()
  if(NOT current STREQUAL points_to)
    file(REMOVE "${STAGE}/lib/${name}")
    file(CREATE_LINK "${points_to}" "${STAGE}/lib/${name}" SYMBOLIC)
  endif()
endforeach()

# 4. libhocurve.a exporting only hoc_*. A Rust staticlib carries the Rust
#    standard library, faer, rayon and the renamed METIS as ~10,000 global
#    symbols, which could clash with a host's own copies (another Rust
#    staticlib, compiler-rt builtins). Link all of its objects into one
#    relocatable object (ld -r through the C compiler), make every global but
#    hoc_* local with objcopy, and archive that one object. Also dropped: the
#    .llvmbc/.llvmcmd sections (bitcode rustc embeds for cross-language LTO);
#    concatenated by ld -r they are no longer valid bitcode, and binutils'
#    LLVM plugin aborts on them. The object links as a whole (no per-member
#    selection); -Wl,--gc-sections removes what a program does not use.
set(staged_a "${STAGE}/lib/libhocurve.a")
if(NOT EXISTS "${staged_a}" OR "${archive}" IS_NEWER_THAN "${staged_a}"
   OR "${CMAKE_CURRENT_LIST_FILE}" IS_NEWER_THAN "${staged_a}")
  set(tmp "${STAGE}/tmp")
  file(REMOVE "${tmp}/hocurve-all.o" "${tmp}/hocurve.o" "${tmp}/libhocurve.a")
  run("${C_COMPILER}" -r -nostdlib -o "${tmp}/hocurve-all.o"
      -Wl,--whole-archive "${archive}" -Wl,--no-whole-archive)
  run("${OBJCOPY}" --remove-section=.llvmbc --remove-section=.llvmcmd
      --wildcard "--keep-global-symbol=hoc_*" "${tmp}/hocurve-all.o" "${tmp}/hocurve.o")
  run("${AR}" rcs "${tmp}/libhocurve.a" "${tmp}/hocurve.o")
  file(REMOVE "${tmp}/hocurve-all.o" "${tmp}/hocurve.o")
  file(RENAME "${tmp}/libhocurve.a" "${staged_a}")
endif()

# 5. The command-line tool.
if(BUILD_CLI)
  run("${CMAKE_COMMAND}" -E copy_if_different "${release}/hocurve" "${STAGE}/bin/hocurve")
endif()
