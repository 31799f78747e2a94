"""The heat-map channels: their names and order.

A keyframe's heat-maps are a float32 array (7, H, W) with values in [0, 1]; element
``[c, i, j]`` is channel ``c`` at pixel ``u = j, v = i``. Channel order (the CNN's output
and the simulator's), fixed for the whole package:

====  ==================  ==================================
 0    point_base          turbine base (paper P^P_g)
 1    point_tower_top     top of the tower (P^P_t)
 2    point_hub           centre of the blades (P^P_r)
 3    point_blade_tip     all three blade tips (P^P_b)
 4    line_tower          tower line (P^L_t)
 5    line_nacelle        tower top -> hub (P^L_r)
 6    line_blade          all three blades (P^L_b)
====  ==================  ==================================
"""

CHANNEL_NAMES = (
    "point_base", "point_tower_top", "point_hub", "point_blade_tip",
    "line_tower", "line_nacelle", "line_blade",
)
NUM_CHANNELS = 7
