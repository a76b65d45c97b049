# Tests of the servo loop's control primitives: PI, input shapers, lost-step detector, encoder
# guard (and their config mappings, engine/control_config.hpp), and the host loop's timing
# (engine/servo_control.hpp). The allocation test is its own
# binary because it interposes malloc.
feedloop_add_test(control_primitives_test
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/pi_controller_test.cpp
          ${CMAKE_CURRENT_SOURCE_DIR}/input_shaper_test.cpp
          ${CMAKE_CURRENT_SOURCE_DIR}/lost_step_detector_test.cpp
          ${CMAKE_CURRENT_SOURCE_DIR}/encoder_guard_test.cpp
          ${CMAKE_CURRENT_SOURCE_DIR}/servo_timing_test.cpp
  LIBS feedloop_control feedloop_engine
  TIMEOUT 60)
feedloop_add_test(control_primitives_rt_test
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/primitives_rt_test.cpp
  LIBS feedloop_control feedloop_engine
  TIMEOUT 60
  LABELS alloc)
# Sim-in-the-loop: PI + lost-step detector on the nonlinear gantry simulator (thesis Sect. 5.4).
feedloop_add_test(control_lost_step_recovery_test
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/lost_step_recovery_test.cpp
  LIBS feedloop_control feedloop_sim feedloop_model
  TIMEOUT 120)
