// localization: work in progress (see the open issue).
#include "safenav/localization.hpp"
