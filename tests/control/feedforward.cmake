# Model-based LPV feedforward (control/feedforward/): the preview inverse on the linear gantry and
# delta models, the factory from the config (engine/control_config.hpp), and (separate binary,
# it replaces malloc) the RT checks.
feedloop_add_test(feedforward_model_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/feedforward_gantry_test.cpp
          ${CMAKE_CURRENT_LIST_DIR}/feedforward_delta_test.cpp
          ${CMAKE_CURRENT_LIST_DIR}/feedforward_factory_test.cpp
          ${CMAKE_CURRENT_LIST_DIR}/velocity_jump_smoother_test.cpp
  LIBS feedloop_control feedloop_engine
  TIMEOUT 120
  LABELS numeric)
feedloop_add_test(feedforward_rt_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/feedforward_rt_test.cpp
  LIBS feedloop_control
  TIMEOUT 120
  LABELS alloc)
