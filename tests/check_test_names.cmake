# Fails when a Catch2 test case name cannot become one ctest entry that runs it (issue 11): a ';'
# splits the name into several entries that each run no test and pass; a name starting with '~'
# or starting or ending with '*' is read by Catch2 as an exclusion or a wildcard, one starting
# with '-' as an option, and a '"' is quoted away.
# Usage: cmake -DEXE=<test executable> -P check_test_names.cmake
execute_process(COMMAND "${EXE}" --list-test-names-only OUTPUT_VARIABLE output)
string(REPLACE ";" "<semicolon>" output "${output}")
string(REPLACE "\n" ";" names "${output}")
set(bad "")
set(count 0)
foreach(name IN LISTS names)
  if(name STREQUAL "")
    continue()
  endif()
  math(EXPR count "${count} + 1")
  if(name MATCHES "<semicolon>|^[-~*]|[*]$|\"")
    string(APPEND bad "\n  ${name}")
  endif()
endforeach()
if(count EQUAL 0)
  message(FATAL_ERROR "${EXE}: lists no test cases")
endif()
if(NOT bad STREQUAL "")
  message(FATAL_ERROR "${EXE}: test case names that ctest cannot run as one test each "
                      "(no ';', no leading '-' or '~', no leading or trailing '*', no '\"'):${bad}")
endif()
message(STATUS "${EXE}: ${count} test case names, each runnable under ctest")
