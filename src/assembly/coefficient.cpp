#include <algorithm>
#include <cmath>

#include "modalcal/assembly.hpp"

namespace modalcal {

namespace {

// One factor's value, gradient and Hessian with respect to its own arguments (a) or (E, nu).
struct FactorDerivatives {
  double value = 0;
  double da = 0, db = 0;            // first derivatives
  double daa = 0, dab = 0, dbb = 0; // second derivatives
};

// kappa = E / (3(1 - 2 nu)),  G = E / (2(1 + nu)) and their exact derivatives.
FactorDerivatives evaluate(const Coefficient::Factor& f, const Vector& theta) {
  FactorDerivatives d;
  const double a = theta[f.a];
  switch (f.kind) {
    case Coefficient::Kind::Property:
      d.value = a;
      d.da = 1;
      break;
    case Coefficient::Kind::BulkFromYoung: {
      const double nu = theta[f.b], s = 1.0 - 2.0 * nu;
      d.value = a / (3 * s);
      d.da = 1 / (3 * s);
      d.db = 2 * a / (3 * s * s);
      d.dab = 2 / (3 * s * s);
      d.dbb = 8 * a / (3 * s * s * s);
      break;
    }
    case Coefficient::Kind::ShearFromYoung: {
      const double nu = theta[f.b], s = 1.0 + nu;
      d.value = a / (2 * s);
      d.da = 1 / (2 * s);
      d.db = -a / (2 * s * s);
      d.dab = -1 / (2 * s * s);
      d.dbb = a / (s * s * s);
      break;
    }
  }
  return d;
}

int local_index(const std::vector<PropertyId>& involved, PropertyId id) {
  return static_cast<int>(std::find(involved.begin(), involved.end(), id) - involved.begin());
}

}  // namespace

double Coefficient::value(const Vector& theta) const {
  double v = 1;
  for (const Factor& f : factors) v *= evaluate(f, theta).value;
  return v;
}

std::vector<PropertyId> Coefficient::involved() const {
  std::vector<PropertyId> ids;
  for (const Factor& f : factors) {
    ids.push_back(f.a);
    if (f.kind != Kind::Property) ids.push_back(f.b);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

// Product rule over the factors: with g_k, H_k each factor's gradient and Hessian (embedded in
// the involved-property space) and P_k the product of the other factors,
// grad = sum_k P_k g_k,  Hess = sum_k P_k H_k + sum_{k != l} P_kl g_k g_l^T.
void Coefficient::derivatives(const Vector& theta, Vector* gradient, Matrix* hessian) const {
  const std::vector<PropertyId> ids = involved();
  const int n = static_cast<int>(ids.size()), m = static_cast<int>(factors.size());
  std::vector<FactorDerivatives> d(m);
  std::vector<Vector> g(m, Vector::Zero(n));
  std::vector<Matrix> h(m, Matrix::Zero(n, n));
  for (int k = 0; k < m; ++k) {
    d[k] = evaluate(factors[k], theta);
    const int ia = local_index(ids, factors[k].a);
    g[k][ia] += d[k].da;
    h[k](ia, ia) += d[k].daa;
    if (factors[k].kind != Kind::Property) {
      const int ib = local_index(ids, factors[k].b);
      g[k][ib] += d[k].db;
      h[k](ia, ib) += d[k].dab;
      h[k](ib, ia) += d[k].dab;
      h[k](ib, ib) += d[k].dbb;
    }
  }
  auto product_except = [&](int skip1, int skip2) {
    double p = 1;
    for (int k = 0; k < m; ++k)
      if (k != skip1 && k != skip2) p *= d[k].value;
    return p;
  };
  gradient->setZero(n);
  hessian->setZero(n, n);
  for (int k = 0; k < m; ++k) {
    const double pk = product_except(k, -1);
    *gradient += pk * g[k];
    *hessian += pk * h[k];
    for (int l = 0; l < m; ++l)
      if (l != k) *hessian += product_except(k, l) * g[k] * g[l].transpose();
  }
}

}  // namespace modalcal
