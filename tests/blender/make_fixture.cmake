# Makes the data the Blender tests share, with the shine CLI:
#   cmake -DSHINE=path/to/shine -DOUT=dir [-DKIND=colour] -P make_fixture.cmake
# OUT/scans: a 4-scan simulated sequence; OUT/map: `shine map` of it (surface.vdb, mesh.ply,
# stats.json, ...) and mesh_adaptive.ply, its surface meshed with adaptivity 0.5.
# With -DKIND=colour: OUT/scans: 6 simulated scans with their front camera's images
# (`--cameras`); OUT/map: `shine map` of them, coloured by the images (mesh.ply red/green/blue,
# surface.vdb's color grid), 0.25 m leaves, 300 iterations, given poses (about 10 s on 2 cores).
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

if(KIND STREQUAL "colour")
    run_shine(simulate -o "${OUT}/scans" --frames 6 --cameras --seed 3 --threads 2 --no-progress)
    run_shine(map "${OUT}/scans" -o "${OUT}/map" --leaf-size-m 0.25 --iterations 300 --no-refine
              --threads 2 --no-eval --quiet)
    return()
elseif(KIND AND NOT KIND STREQUAL "plain")
    message(FATAL_ERROR "make_fixture.cmake: -DKIND=${KIND}: expected plain or colour")
endif()

run_shine(simulate -o "${OUT}/scans" --frames 4 --seed 3 --threads 2 --no-progress)
run_shine(map "${OUT}/scans" -o "${OUT}/map" --iterations 300 --threads 2 --no-eval --quiet)
run_shine(mesh "${OUT}/map/surface.vdb" -o "${OUT}/map/mesh_adaptive.ply" --adaptivity 0.5)
