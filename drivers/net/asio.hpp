// The one place Boost.Asio is included. Boost 1.74's Asio under C++20 needs <utility> first.
#pragma once

#include <boost/asio.hpp>
#include <utility>
