// placement: work in progress (see the open issue).
#include "safenav/placement.hpp"
