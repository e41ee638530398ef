#pragma once
// navigation: work in progress (see the open issue).
namespace safenav {}
