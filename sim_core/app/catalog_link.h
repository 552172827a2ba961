#pragma once
/// @file
/// The simulation server's SceneCatalog over the catalogue database (catalog/catalog.h): what
/// LOAD_AVATAR, LOAD_COSTUME, LOAD_ANIMATION and SAVE_VERSION do to the scene
/// (docs/processes.md). A library of its own (costume::sim_server_catalog) so that the server
/// library links no database.

#include <memory>
#include <string>

#include "catalog/catalog.h"
#include "sim_core/app/sim_server.h"

namespace costume::sim_app {

/// Opens the catalogue at `url` (catalog::Catalog::Open: created and seeded when new) as the
/// server's SceneCatalog. Throws sim::InputError naming the URL.
std::unique_ptr<SceneCatalog> OpenSceneCatalog(const std::string& url);

/// `catalog` (already open) as the server's SceneCatalog.
std::unique_ptr<SceneCatalog> MakeSceneCatalog(std::unique_ptr<catalog::Catalog> catalog);

}  // namespace costume::sim_app
