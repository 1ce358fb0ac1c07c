# Finds PCL and exposes it as the interface targets objscan::pcl (all the components below) and
# objscan::pcl_sac (sample consensus only), PCL headers as system headers.
# Debian 12's PCL config loads VTK, whose VTK::mpi target needs MPI::MPI_C to exist first.
if(NOT TARGET objscan::pcl)
  find_package(MPI QUIET COMPONENTS C)
  find_package(PCL 1.12 REQUIRED COMPONENTS common io kdtree search sample_consensus)
  add_library(objscan_pcl INTERFACE)
  add_library(objscan::pcl ALIAS objscan_pcl)
  target_include_directories(objscan_pcl SYSTEM INTERFACE ${PCL_INCLUDE_DIRS})
  target_link_libraries(objscan_pcl INTERFACE ${PCL_LIBRARIES})
  target_compile_definitions(objscan_pcl INTERFACE ${PCL_DEFINITIONS})
  # PCL's sample consensus (RANSAC), for discovery's support planes, which should not link PCL's
  # I/O and, through it, VTK. Its templates are compiled from the headers (PCL_NO_PRECOMPILE, see
  # discovery/src/supports.cpp), so only pcl_common is linked.
  add_library(objscan_pcl_sac INTERFACE)
  add_library(objscan::pcl_sac ALIAS objscan_pcl_sac)
  target_include_directories(objscan_pcl_sac SYSTEM INTERFACE ${PCL_INCLUDE_DIRS})
  target_link_libraries(objscan_pcl_sac INTERFACE ${PCL_COMMON_LIBRARIES})
  target_compile_definitions(objscan_pcl_sac INTERFACE ${PCL_DEFINITIONS})
endif()
