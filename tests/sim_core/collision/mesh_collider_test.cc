#include "sim_core/collision/mesh_collider.h"
