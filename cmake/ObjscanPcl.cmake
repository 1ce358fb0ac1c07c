# Finds PCL and exposes it as the interface target objscan::pcl (PCL headers as system headers).
# Debian 12's PCL config loads VTK, whose VTK::mpi target needs MPI::MPI_C to exist first.
if(NOT TARGET objscan::pcl)
  find_package(MPI QUIET COMPONENTS C)
  find_package(PCL 1.12 REQUIRED COMPONENTS common io kdtree search)
  add_library(objscan_pcl INTERFACE)
  add_library(objscan::pcl ALIAS objscan_pcl)
  target_include_directories(objscan_pcl SYSTEM INTERFACE ${PCL_INCLUDE_DIRS})
  target_link_libraries(objscan_pcl INTERFACE ${PCL_LIBRARIES})
  target_compile_definitions(objscan_pcl INTERFACE ${PCL_DEFINITIONS})
endif()
