# Smoke check of the kernel benchmark program (ctest: bench_kernels_runs). It runs every benchmark
# once, briefly, and checks that each kernel family reported at least one run with a positive,
# finite time and no error. It checks that the benchmarks still run, not how fast they are: the
# figures are for docs/performance.md, measured on an idle machine.
#   cmake -DBENCH=path/to/shine_kernel_bench -DOUT=work/dir -P check_kernel_bench.cmake
if(NOT BENCH OR NOT OUT)
    message(FATAL_ERROR "usage: cmake -DBENCH=<shine_kernel_bench> -DOUT=<dir> -P ${CMAKE_CURRENT_LIST_FILE}")
endif()
file(MAKE_DIRECTORY "${OUT}")
set(_json "${OUT}/kernel_bench.json")
file(REMOVE "${_json}")
execute_process(COMMAND "${BENCH}" --benchmark_min_time=0.01 --benchmark_out=${_json}
                        --benchmark_out_format=json
                RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "${BENCH} exited with ${_rc}:\n${_out}\n${_err}")
endif()
if(NOT EXISTS "${_json}")
    message(FATAL_ERROR "${BENCH} wrote no ${_json}")
endif()
file(READ "${_json}" _text)
string(JSON _count LENGTH "${_text}" benchmarks)

# The kernels the issue asks for (interpolation, decoder forward and backward, Adam step,
# sampling, bake) and the training step and normals around them.
set(_families BM_EncodeAndGather BM_DecoderPerSample BM_DecoderBatched BM_SampleLossGradient
              BM_BatchLossGradient BM_BatchLossGradientFloat16 BM_AdamStepRows BM_SampleRay BM_TrainerStep
              BM_PointKdTreeBuild BM_PointKdTreeNearest BM_EstimateRayNormalsWindow BM_Bake)
foreach(_family ${_families})
    set(_seen_${_family} 0)
endforeach()
math(EXPR _last "${_count} - 1")
foreach(_i RANGE ${_last})
    string(JSON _name GET "${_text}" benchmarks ${_i} name)
    string(JSON _time GET "${_text}" benchmarks ${_i} real_time)
    string(JSON _iterations GET "${_text}" benchmarks ${_i} iterations)
    string(JSON _error ERROR_VARIABLE _no_error GET "${_text}" benchmarks ${_i} error_occurred)
    if(_no_error STREQUAL "NOTFOUND" AND _error)
        string(JSON _message GET "${_text}" benchmarks ${_i} error_message)
        message(FATAL_ERROR "${_name}: ${_message}")
    endif()
    if(NOT _time MATCHES "^[0-9.eE+-]+$" OR _time LESS_EQUAL 0 OR _iterations LESS 1)
        message(FATAL_ERROR "${_name}: time ${_time} over ${_iterations} iterations")
    endif()
    string(REGEX REPLACE "/.*" "" _family "${_name}")
    if(DEFINED _seen_${_family})
        math(EXPR _seen_${_family} "${_seen_${_family}} + 1")
    endif()
endforeach()
foreach(_family ${_families})
    if(_seen_${_family} EQUAL 0)
        message(FATAL_ERROR "${_family} reported no run")
    endif()
    message(STATUS "${_family}: ${_seen_${_family}} run(s)")
endforeach()
