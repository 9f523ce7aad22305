"""The thesis's printed snakeboard equations (3.93–3.94, Table 3.3) integrated as printed and
with each factor-2 fix, to show which errata matter for the PD run (docs/thesis-errata.md).

Run: python experiments/thesis_printed_equations.py
"""
import numpy as np
from scipy.integrate import solve_ivp

m,J,Jr,Jw=0.5,0.3,0.2,0.1
r=np.sqrt((J+Jr+2*Jw)/m)
kp,kd=10,5
def make(psi_factor=2.0, ptpsi0_factor=2.0):
    def f(t,z):
        x,y,th,ps,ph,p,pps,pph=z
        D=-Jr+2*m*r**2+Jr*np.cos(2*ph)
        xi1=p/(2*m*r)-r*np.sin(2*ph)/D*pps
        xi3=-2*np.sin(ph)**2/D*pps+np.tan(ph)/(2*m*r**2)*p
        psid=psi_factor*m*r**2/(Jr*(m*r**2-Jr*np.sin(ph)**2))*pps
        phid=pph/(2*Jw)
        pd=pph/(2*Jw)*(4*m*r**2*np.cos(ph)**2/D*pps-np.tan(ph)*p)
        tpsi=-np.sin(t)+kp*(np.sin(t)-ps)+kd*(np.cos(t)-psid)
        tphi=-np.cos(t)+kp*(np.cos(t)-ph)+kd*(-np.sin(t)-phid)
        ppsd=pph/(2*Jw)*(-Jr/(2*m*r**2)*p+Jr*np.sin(2*ph)/(Jr-2*m*r**2-Jr*np.cos(2*ph))*pps)+tpsi
        return [np.cos(th)*xi1,np.sin(th)*xi1,xi3,psid,phid,pd,ppsd,tphi]
    ph0=1.0
    psd0=1.0
    z0=[0,0,0,0,ph0,Jr*np.sin(2*ph0)*psd0,
        ptpsi0_factor*Jr/(m*r**2)*(m*r**2-Jr*np.sin(ph0)**2)*psd0, 2*Jw*0.0]
    return f,z0
def main(argv=None):
  for pf,icf in [(2,2),(1,1),(2,1),(1,2)]:
    f,z0=make(pf,icf)
    s=solve_ivp(f,(0,10*np.pi),z0,method='DOP853',rtol=1e-12,atol=1e-12)
    print(f'psi_dot factor {pf}, pt_psi(0) factor {icf}: x(10pi)={s.y[0,-1]:.7f} y={s.y[1,-1]:.8f}')

  return 0


if __name__ == '__main__':
    raise SystemExit(main())
