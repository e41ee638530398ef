// vehicle_loop — embed the safenav core in a vehicle program.
//
// A simulated vehicle drives a gentle S-curve. Each control tick the program
// predicts with the Battlefield Motion Model (SafeNav eqs. 3–9) and, whenever
// a LanBLoc position fix arrives (here every 5th tick, simulated with the
// paper's RMSE of 0.0142 m in X and 0.039 m in Y), updates an EKF (eqs. 10–14).
//
//   vehicle_loop [steps]      prints the final error and exits 0 on success
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include <safenav/filters.hpp>
#include <safenav/measurement.hpp>
#include <safenav/motion.hpp>

int main(int argc, char** argv) {
  const int steps = argc > 1 ? std::atoi(argv[1]) : 400;
  if (steps <= 0) {
    std::fprintf(stderr, "steps must be > 0\n");
    return 2;
  }
  safenav::BmmParams params;  // defaults; dt = 0.05 s
  const safenav::Bmm vehicle(params);

  // The true vehicle starts at the origin heading east at 2 m/s.
  safenav::State truth(0.0, 0.0, 2.0, 0.0);
  // The filter starts with a rough idea of where it is.
  safenav::StateCov P0 = safenav::StateCov::Zero();
  P0.diagonal() << 0.5 * 0.5, 0.5 * 0.5, 0.2 * 0.2, 0.1 * 0.1;
  safenav::Ekf ekf(params, safenav::State(0.3, -0.2, 2.0, 0.05), P0);
  ekf.set_gate(0.999);  // reject wild fixes

  Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
  R.diagonal() << 0.0142 * 0.0142, 0.039 * 0.039;
  const auto lanbloc = safenav::MeasurementModel::position(R);

  std::mt19937_64 gen(42);
  std::normal_distribution<double> n01(0.0, 1.0);
  int fixes = 0;
  for (int k = 0; k < steps; ++k) {
    const double t = k * params.dt;
    const safenav::Control u(2.0, 0.02 * std::sin(0.5 * t));  // desired speed, heading change
    const Eigen::Vector4d eps(params.position_noise * n01(gen), params.position_noise * n01(gen),
                              params.speed_noise * n01(gen), params.heading_noise * n01(gen));
    truth = vehicle.transition(truth, u, eps);  // the real vehicle moves
    ekf.predict(u);                             // the filter predicts with the BMM
    if (k % 5 == 4) {                           // a LanBLoc fix arrives
      const Eigen::Vector2d z(truth.x() + 0.0142 * n01(gen), truth.y() + 0.039 * n01(gen));
      if (ekf.update(lanbloc, z).accepted) ++fixes;
    }
  }
  const double err = (ekf.x().head<2>() - truth.head<2>()).norm();
  const double sigma = std::sqrt(ekf.P().topLeftCorner<2, 2>().trace());
  std::printf("steps=%d fixes=%d truth=(%.3f, %.3f) estimate=(%.3f, %.3f) error=%.4f m sigma=%.4f m\n", steps,
              fixes, truth.x(), truth.y(), ekf.x().x(), ekf.x().y(), err, sigma);
  return err < 0.5 ? 0 : 1;
}
