# Injected with -DCMAKE_PROJECT_INCLUDE when msg_defs is built against the ROS 2 PyPI wheels.
#
# The wheels export targets such as std_msgs::std_msgs__rosidl_generator_py whose
# INTERFACE_INCLUDE_DIRECTORIES name the Python and numpy include directories of the machine
# that built the wheels (/opt/python/...). CMake refuses to generate with non-existent include
# paths, so at the end of the top-level CMakeLists.txt we replace them with this venv's paths.
cmake_minimum_required(VERSION 3.21)

function(euc_fix_wheel_include_dirs)
  if(NOT DEFINED Python3_INCLUDE_DIRS OR NOT DEFINED Python3_NumPy_INCLUDE_DIRS)
    find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)
  endif()
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs OR NOT "${_dirs}" MATCHES "/opt/python/")
      continue()
    endif()
    set(_fixed "")
    foreach(_dir IN LISTS _dirs)
      if(_dir MATCHES "^/opt/python/.*numpy")
        list(APPEND _fixed ${Python3_NumPy_INCLUDE_DIRS})
      elseif(_dir MATCHES "^/opt/python/")
        list(APPEND _fixed ${Python3_INCLUDE_DIRS})
      else()
        list(APPEND _fixed "${_dir}")
      endif()
    endforeach()
    list(REMOVE_DUPLICATES _fixed)
    set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_fixed}")
  endforeach()
endfunction()

cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL euc_fix_wheel_include_dirs)
