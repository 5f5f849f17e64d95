// The Ipopt TNLP over a FullSpaceProblem: it only maps the problem (sizes, bounds, start,
// values from the problem's one indexing helper) and reports iterations; everything numerical
// lives in FullSpaceProblem. Ipopt 3.11.9 (Debian) specifics: no get_curr_iterate, so the
// iterate is recovered through OrigIpoptNLP / TNLPAdapter::ResortX (no user scaling is used,
// nothing to undo); Ipopt::Index is qualified because Eigen has an Index too.

#include <coin/IpIpoptApplication.hpp>
#include <coin/IpIpoptCalculatedQuantities.hpp>
#include <coin/IpIpoptData.hpp>
#include <coin/IpOrigIpoptNLP.hpp>
#include <coin/IpTNLP.hpp>
#include <coin/IpTNLPAdapter.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

#include "fullspace/ipopt/ipopt_run.hpp"
#include "fullspace/structured_kkt.hpp"

namespace modalcal::detail {

namespace {

using Ipopt::Number;

std::string status_name(Ipopt::ApplicationReturnStatus status) {
  switch (status) {
    case Ipopt::Solve_Succeeded: return "Solve_Succeeded";
    case Ipopt::Solved_To_Acceptable_Level: return "Solved_To_Acceptable_Level";
    case Ipopt::Infeasible_Problem_Detected: return "Infeasible_Problem_Detected";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "Search_Direction_Becomes_Too_Small";
    case Ipopt::Diverging_Iterates: return "Diverging_Iterates";
    case Ipopt::User_Requested_Stop: return "User_Requested_Stop";
    case Ipopt::Feasible_Point_Found: return "Feasible_Point_Found";
    case Ipopt::Maximum_Iterations_Exceeded: return "Maximum_Iterations_Exceeded";
    case Ipopt::Restoration_Failed: return "Restoration_Failed";
    case Ipopt::Error_In_Step_Computation: return "Error_In_Step_Computation";
    case Ipopt::Maximum_CpuTime_Exceeded: return "Maximum_CpuTime_Exceeded";
    case Ipopt::Not_Enough_Degrees_Of_Freedom: return "Not_Enough_Degrees_Of_Freedom";
    case Ipopt::Invalid_Problem_Definition: return "Invalid_Problem_Definition";
    case Ipopt::Invalid_Option: return "Invalid_Option";
    case Ipopt::Invalid_Number_Detected: return "Invalid_Number_Detected";
    case Ipopt::Unrecoverable_Exception: return "Unrecoverable_Exception";
    case Ipopt::NonIpopt_Exception_Thrown: return "NonIpopt_Exception_Thrown";
    case Ipopt::Insufficient_Memory: return "Insufficient_Memory";
    case Ipopt::Internal_Error: return "Internal_Error";
  }
  return "Unknown_Status";
}

// Likely causes, for users who never read Ipopt's documentation.
std::string explain(Ipopt::ApplicationReturnStatus status) {
  switch (status) {
    case Ipopt::Restoration_Failed:
    case Ipopt::Infeasible_Problem_Detected:
      return "Ipopt could not restore feasibility of the eigenproblem constraints: the start is far from "
             "any eigenpair, or K(p) lost definiteness near a bound";
    case Ipopt::Error_In_Step_Computation:
    case Ipopt::Search_Direction_Becomes_Too_Small:
      return "the KKT system could not be solved usefully: repeated eigenvalues among the calibrated modes, or "
             "parameters with no influence on the data";
    case Ipopt::Invalid_Number_Detected:
      return "a NaN or Inf in the model at a trial point (a parameter without bounds left its physical range)";
    case Ipopt::Diverging_Iterates: return "the iterates diverge: add bounds to the parameters";
    case Ipopt::Insufficient_Memory: return "MUMPS ran out of memory: reduce the mesh or the number of modes";
    default: return "";
  }
}

class CalibrationTnlp : public Ipopt::TNLP {
 public:
  CalibrationTnlp(FullSpaceProblem& problem, const Vector& x0, const Vector& y0, double mu_init,
                  const NewtonCallback& callback, NewtonPhaseResult* result)
      : problem_(problem), x0_(x0), y0_(y0), mu_init_(mu_init), callback_(callback), result_(result) {}

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g, Ipopt::Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = problem_.num_variables();
    m = problem_.num_constraints();
    nnz_jac_g = problem_.jacobian_layout().nonzeros();
    nnz_h_lag = problem_.hessian_layout().nonzeros();
    index_style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Ipopt::Index, Number* x_l, Number* x_u, Ipopt::Index m, Number* g_l, Number* g_u) override {
    problem_.bounds(x_l, x_u);
    lower_.assign(x_l, x_l + problem_.num_variables());
    upper_.assign(x_u, x_u + problem_.num_variables());
    std::fill(g_l, g_l + m, 0.0);
    std::fill(g_u, g_u + m, 0.0);
    return true;
  }

  bool get_starting_point(Ipopt::Index n, bool init_x, Number* x, bool init_z, Number* z_L, Number* z_U, Ipopt::Index m,
                          bool init_lambda, Number* lambda) override {
    if (init_x) std::copy(x0_.data(), x0_.data() + n, x);
    if (init_lambda) std::copy(y0_.data(), y0_.data() + m, lambda);
    if (init_z)  // on the central path for the starting barrier parameter
      for (int k = 0; k < n; ++k) {
        z_L[k] = lower_[k] > -1e19 ? mu_init_ / std::max(x0_[k] - lower_[k], 1e-12) : 0.0;
        z_U[k] = upper_[k] < 1e19 ? mu_init_ / std::max(upper_[k] - x0_[k], 1e-12) : 0.0;
      }
    return true;
  }

  bool eval_f(Ipopt::Index, const Number* x, bool, Number& value) override {
    value = problem_.objective(x);
    return std::isfinite(value);
  }
  bool eval_grad_f(Ipopt::Index, const Number* x, bool, Number* gradient) override {
    problem_.objective_gradient(x, gradient);
    return true;
  }
  bool eval_g(Ipopt::Index, const Number* x, bool, Ipopt::Index, Number* g) override {
    problem_.constraints(x, g);
    return true;
  }
  bool eval_jac_g(Ipopt::Index, const Number* x, bool, Ipopt::Index, Ipopt::Index, Ipopt::Index* rows,
                  Ipopt::Index* cols, Number* values) override {
    if (values == nullptr)
      problem_.jacobian_layout().structure(rows, cols);
    else
      problem_.jacobian_values(x, values);
    return true;
  }
  bool eval_h(Ipopt::Index, const Number* x, bool, Number sigma, Ipopt::Index, const Number* lambda, bool, Ipopt::Index,
              Ipopt::Index* rows, Ipopt::Index* cols, Number* values) override {
    if (values == nullptr) {
      problem_.hessian_layout().structure(rows, cols);
    } else {
      problem_.hessian_values(x, sigma, lambda, values);
      ++result_->hessian_evaluations;
    }
    return true;
  }

  bool intermediate_callback(Ipopt::AlgorithmMode mode, Ipopt::Index iter, Number objective, Number inf_pr,
                             Number inf_du, Number mu, Number, Number regularization_size, Number, Number alpha_pr,
                             Ipopt::Index,
                             const Ipopt::IpoptData* data, Ipopt::IpoptCalculatedQuantities* quantities) override {
    result_->iterations = iter;
    if (!callback_) return true;
    NewtonIteration info =
        NewtonIteration::at(iter, objective, inf_pr, inf_du, iter == 0 ? 0 : alpha_pr, regularization_size);
    info.mu = mu;
    // The iterate, in the TNLP's ordering; unavailable during the restoration phase.
    const double* x = nullptr;
    if (mode == Ipopt::RegularMode && data && quantities) {
      info.complementarity = quantities->curr_complementarity(0.0, Ipopt::NORM_MAX);
      auto* nlp = dynamic_cast<Ipopt::OrigIpoptNLP*>(Ipopt::GetRawPtr(quantities->GetIpoptNLP()));
      auto* adapter = nlp ? dynamic_cast<Ipopt::TNLPAdapter*>(Ipopt::GetRawPtr(nlp->nlp())) : nullptr;
      if (adapter) {
        current_.resize(problem_.num_variables());
        adapter->ResortX(*data->curr()->x(), current_.data());
        x = current_.data();
      }
    }
    if (x == nullptr) return true;
    return callback_(info, x);
  }

  void finalize_solution(Ipopt::SolverReturn, Ipopt::Index n, const Number* x, const Number*, const Number*,
                         Ipopt::Index m, const Number*, const Number* lambda, Number objective,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    result_->x = Eigen::Map<const Vector>(x, n);
    result_->y = Eigen::Map<const Vector>(lambda, m);
    result_->objective = objective;
  }

 private:
  FullSpaceProblem& problem_;
  const Vector& x0_;
  const Vector& y0_;
  double mu_init_;
  const NewtonCallback& callback_;
  NewtonPhaseResult* result_;
  std::vector<double> lower_, upper_;
  Vector current_;
};

}  // namespace

NewtonPhaseResult run_ipopt(FullSpaceProblem& problem, const Vector& x0, const Vector& y0, const NewtonPhaseOptions& options,
                         const NewtonCallback& callback) {
  NewtonPhaseResult result;
  // Declared before the application: Ipopt's solver instances must not outlive the registration.
  KktFactorizationCounts counts;
  std::optional<StructuredKktScope> structured;
  if (options.structured_kkt) structured.emplace(problem, &counts, options.shared_factorization);
  Ipopt::SmartPtr<Ipopt::TNLP> tnlp = new CalibrationTnlp(problem, x0, y0, options.mu_init, callback, &result);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  Ipopt::OptionsList& o = *app->Options();
  o.SetStringValue("sb", "yes");
  o.SetIntegerValue("print_level", options.print_level);
  o.SetIntegerValue("max_iter", options.max_iterations);
  o.SetNumericValue("tol", options.tolerance);
  o.SetNumericValue("constr_viol_tol", options.tolerance);
  o.SetNumericValue("dual_inf_tol", options.tolerance);
  o.SetNumericValue("compl_inf_tol", options.tolerance);
  // The problem is nondimensionalized by FullSpaceProblem; Ipopt's gradient-based scaling
  // would rescale it again depending on the start.
  o.SetStringValue("nlp_scaling_method", "none");
  // `pardiso` is the structured solver (structured_kkt.hpp, through libpardiso.so); it reads the
  // KKT blocks as the problem defines them, so Ipopt must not rescale the matrix.
  o.SetStringValue("linear_solver", options.structured_kkt ? "pardiso" : "mumps");
  o.SetStringValue("linear_system_scaling", "none");
  // MUMPS's default pivot tolerance (1e-6) accepts pivots small enough to miscount the inertia
  // of these saddle-point systems (one spurious negative eigenvalue per mode was seen), and Ipopt
  // then regularizes the Hessian by up to 1e2 and stalls. A tolerance of 0.1 costs little fill.
  o.SetNumericValue("mumps_pivtol", 0.1);
  o.SetStringValue("hessian_approximation", options.exact_hessian ? "exact" : "limited-memory");
  // Warm start from the forward solution and adjoint multipliers, close to the central path.
  o.SetStringValue("warm_start_init_point", "yes");
  o.SetNumericValue("mu_init", options.mu_init);
  o.SetNumericValue("warm_start_bound_push", 1e-9);
  o.SetNumericValue("warm_start_bound_frac", 1e-9);
  o.SetNumericValue("warm_start_mult_bound_push", 1e-12);
  if (options.start_with_restoration) o.SetStringValue("start_with_resto", "yes");
  if (options.derivative_test) {
    o.SetStringValue("derivative_test", options.exact_hessian ? "second-order" : "first-order");
    o.SetNumericValue("derivative_test_perturbation", 1e-6);
  }
  Ipopt::ApplicationReturnStatus status = app->Initialize();
  if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(tnlp);
  result.status = status_name(status);
  result.structured_factorizations = counts.structured;
  result.mumps_factorizations = counts.mumps;
  result.shared_modes = counts.shared_modes;
  result.shared_failures = counts.shared_failures;
  result.solved = status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level;
  result.stopped_by_callback = status == Ipopt::User_Requested_Stop;
  result.max_iterations = status == Ipopt::Maximum_Iterations_Exceeded;
  if (!result.solved && !result.stopped_by_callback) {
    result.message = "Ipopt: " + result.status;
    const std::string why = explain(status);
    if (!why.empty()) result.message += " (" + why + ")";
  }
  if (result.x.size() == 0) result.x = x0;
  if (result.y.size() == 0) result.y = y0;
  return result;
}

}  // namespace modalcal::detail
