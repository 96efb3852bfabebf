// Stand-in for libnifalcon's falcon/core/FalconCore.h: the error-code base of the components.
// libnifalcon uses boost::array and boost::shared_ptr; these stand-ins use std::array and
// std::shared_ptr, which the backend uses the same way (operator[], ->, brace initialisation).
#pragma once

namespace libnifalcon {

class FalconCore {
 public:
  FalconCore() = default;
  virtual ~FalconCore() = default;
  int getErrorCode() const { return m_errorCode; }

 protected:
  int m_errorCode = 0;
};

}  // namespace libnifalcon
