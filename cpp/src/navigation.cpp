// navigation: work in progress (see the open issue).
#include "safenav/navigation.hpp"
