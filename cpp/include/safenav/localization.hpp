#pragma once
// localization: work in progress (see the open issue).
namespace safenav {}
