# The safety libraries: core, hal, motion, safelink, controller (DESIGN.md), included by the top-level
# CMakeLists.txt and by channel B's own tree (pair/clang/CMakeLists.txt, built by Clang:
# SPEC §14, one compiler fault is not a common cause). SAFESTATE_ROOT: the repository.
set(SAFESTATE_WARNINGS -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Wold-style-cast
                       -Wnon-virtual-dtor -Wcast-align -Wdouble-promotion)
if(SAFESTATE_WERROR)
  list(APPEND SAFESTATE_WARNINGS -Werror)
endif()

# The safety core: no heap, no exceptions, no RTTI, no OS calls (DESIGN.md). The
# same flags are used for the Cortex-M4 build (tools/scripts/embedded.sh).
function(safestate_rt_library name)
  target_compile_options(${name} PRIVATE ${SAFESTATE_WARNINGS} -Wnull-dereference -fno-exceptions -fno-rtti)
endfunction()

# Every safety function is a monitor in a file of its own (core/include/safestate/core/
# monitor.hpp): a new one is picked up from its folder.
file(GLOB SAFESTATE_MONITOR_SOURCES CONFIGURE_DEPENDS ${SAFESTATE_ROOT}/core/src/monitors/*.cpp)
add_library(safestate_core STATIC
  ${SAFESTATE_ROOT}/core/src/arm.cpp
  ${SAFESTATE_ROOT}/core/src/arming.cpp
  ${SAFESTATE_ROOT}/core/src/collaborative.cpp
  ${SAFESTATE_MONITOR_SOURCES}
  ${SAFESTATE_ROOT}/core/src/alarms.cpp
  ${SAFESTATE_ROOT}/core/src/commands.cpp
  ${SAFESTATE_ROOT}/core/src/output_check.cpp
  ${SAFESTATE_ROOT}/core/src/status.cpp
  ${SAFESTATE_ROOT}/core/src/stopping.cpp
  ${SAFESTATE_ROOT}/core/src/config.cpp
  ${SAFESTATE_ROOT}/core/src/describe.cpp
  ${SAFESTATE_ROOT}/core/src/guards.cpp
  ${SAFESTATE_ROOT}/core/src/names.cpp
  ${SAFESTATE_ROOT}/core/src/signals.cpp
  ${SAFESTATE_ROOT}/core/src/supervisor.cpp)
target_include_directories(safestate_core PUBLIC ${SAFESTATE_ROOT}/core/include)
safestate_rt_library(safestate_core)
add_library(safestate::core ALIAS safestate_core)

add_library(safestate_hal INTERFACE)
target_include_directories(safestate_hal INTERFACE ${SAFESTATE_ROOT}/hal/include)
target_link_libraries(safestate_hal INTERFACE safestate_core)

add_library(safestate_motion STATIC ${SAFESTATE_ROOT}/motion/src/back_off.cpp ${SAFESTATE_ROOT}/motion/src/kinematics.cpp ${SAFESTATE_ROOT}/motion/src/limits.cpp ${SAFESTATE_ROOT}/motion/src/motion_controller.cpp)
target_include_directories(safestate_motion PUBLIC ${SAFESTATE_ROOT}/motion/include)
target_link_libraries(safestate_motion PUBLIC safestate_core safestate_hal)
safestate_rt_library(safestate_motion)

# The black channel's safety layer (issue 37, docs/black-channel.md): containers, CRC-64/XZ and the
# two ends' state machines. The channels check their containers themselves (controller's
# SafetyLinks), so channel B's Clang tree builds it too.
add_library(safestate_safelink STATIC ${SAFESTATE_ROOT}/safelink/src/container.cpp ${SAFESTATE_ROOT}/safelink/src/link.cpp)
target_include_directories(safestate_safelink PUBLIC ${SAFESTATE_ROOT}/safelink/include)
safestate_rt_library(safestate_safelink)

# The scan cycle: core + motion over the process image. Same rules as core/.
add_library(safestate_controller STATIC ${SAFESTATE_ROOT}/controller/src/controller.cpp ${SAFESTATE_ROOT}/controller/src/cell.cpp ${SAFESTATE_ROOT}/controller/src/platform.cpp
                                         ${SAFESTATE_ROOT}/controller/src/demo_program.cpp ${SAFESTATE_ROOT}/controller/src/cross_check.cpp
                                         ${SAFESTATE_ROOT}/controller/src/channels.cpp ${SAFESTATE_ROOT}/controller/src/safety_links.cpp)
target_include_directories(safestate_controller PUBLIC ${SAFESTATE_ROOT}/controller/include)
target_link_libraries(safestate_controller PUBLIC safestate_motion safestate_safelink)
safestate_rt_library(safestate_controller)
