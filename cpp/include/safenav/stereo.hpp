#pragma once
// stereo: work in progress (see the open issue).
namespace safenav {}
