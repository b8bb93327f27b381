"""The restaurant's floor: map files, the occupancy grid, path planning and distances.

Owns :mod:`~serveur.maps.mapio` (ROS ``map_server`` maps and waypoint files),
:mod:`~serveur.maps.navigation` (grid, planner, laser ray casting),
:mod:`~serveur.maps.distances` (path distances between waypoints, computed off the server's
heap), :mod:`~serveur.maps.memory` (giving freed heap back to the OS after them),
:mod:`~serveur.maps.floorplan` (a floor-plan image turned into a map: threshold, edits, scale
from two measures, resampling) and :mod:`~serveur.maps.align` (one map fitted onto another from
matched points). Pure
computation and file reading: both the server and the simulator use it.

May import: serveur.robots.rosbridge.
"""

__all__: list[str] = []
