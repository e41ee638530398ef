#pragma once
// placement: work in progress (see the open issue).
namespace safenav {}
