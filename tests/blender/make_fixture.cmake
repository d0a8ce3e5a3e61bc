# Makes the data the Blender tests share, with the shine CLI:
#   cmake -DSHINE=path/to/shine -DOUT=dir -P make_fixture.cmake
# OUT/scans: a 4-scan simulated sequence; OUT/map: `shine map` of it (surface.vdb, mesh.ply,
# stats.json, ...) and mesh_adaptive.ply, its surface meshed with adaptivity 0.5.
foreach(_var SHINE OUT)
    if(NOT ${_var})
        message(FATAL_ERROR "make_fixture.cmake: -D${_var}=... is required")
    endif()
endforeach()
file(REMOVE_RECURSE "${OUT}")

function(run_shine)
    execute_process(COMMAND "${SHINE}" ${ARGN} RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "shine ${ARGN} failed: ${_rc}")
    endif()
endfunction()

run_shine(simulate -o "${OUT}/scans" --frames 4 --seed 3 --threads 2 --no-progress)
run_shine(map "${OUT}/scans" -o "${OUT}/map" --iterations 300 --threads 2 --no-eval --quiet)
run_shine(mesh "${OUT}/map/surface.vdb" -o "${OUT}/map/mesh_adaptive.ply" --adaptivity 0.5)
